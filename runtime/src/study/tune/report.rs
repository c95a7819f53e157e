//! The outputs of `companion tune`: `preset.toml` (the best candidate as a `--config` file),
//! `report.json` (every candidate, the best, the Pareto front), `candidates.csv` and
//! `pareto.svg` (tracked fraction against effort).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use serde::Serialize;

use super::{best_of, Candidate, Tuning};
use crate::domain::plots::PlotError;
use crate::study::knobs::{self, Knob};

/// Why the outputs of `companion tune` could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// No candidate is valid, so there is no preset.
    #[error("no candidate satisfies the law's rules")]
    NoValidCandidate,
    /// The preset cannot be put as TOML.
    #[error("writing the preset")]
    Preset(#[source] toml::ser::Error),
    /// The report cannot be put as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The output folder cannot be made.
    #[error("creating {}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A file of the report cannot be written.
    #[error("writing {file}")]
    Write {
        /// `preset.toml`, `report.json` or `candidates.csv`.
        file: &'static str,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// `pareto.svg` cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// The error of writing `file`.
fn writing(file: &'static str) -> impl FnOnce(std::io::Error) -> ReportError {
    move |source| ReportError::Write { file, source }
}

/// Every candidate, the best and the Pareto front.
#[derive(Clone, Debug, Serialize)]
pub struct TuneReport {
    /// The runs of the set.
    pub runs: Vec<String>,
    /// The spatial arm they ran (`tune --arm`); `None`: the paper's planar arm.
    pub arm: Option<String>,
    /// The space searched.
    pub space: Vec<(Knob, [f64; 2])>,
    /// The effort weight (s/m).
    pub effort_weight: f64,
    /// The seed.
    pub seed: u64,
    /// The starts each run ran from (one: the arm's home).
    pub starts: crate::study::starts::Starts,
    /// `‖e_p‖` below this was tracked.
    pub tolerance: f64,
    /// Every candidate, in evaluation order.
    pub candidates: Vec<Candidate>,
    /// The best candidate's index (`None` if none was valid).
    pub best: Option<usize>,
    /// The indices of the Pareto front (no other candidate tracks at least as much with at
    /// most as much effort, one of them strictly), by increasing effort.
    pub pareto: Vec<usize>,
}

impl TuneReport {
    /// The report of `candidates`.
    pub fn new(t: &Tuning, candidates: Vec<Candidate>) -> Self {
        let best = best_of(&candidates).map(|c| c.index);
        let valid: Vec<&Candidate> = candidates.iter().filter(|c| c.cost.is_finite()).collect();
        let mut pareto: Vec<&Candidate> = valid
            .iter()
            .filter(|c| {
                !valid.iter().any(|o| {
                    o.tracked >= c.tracked
                        && o.effort <= c.effort
                        && (o.tracked > c.tracked || o.effort < c.effort)
                })
            })
            .copied()
            .collect();
        pareto.sort_by(|a, b| a.effort.total_cmp(&b.effort).then(a.index.cmp(&b.index)));
        let mut seen: Vec<(u64, u64)> = Vec::new();
        pareto.retain(|c| {
            let key = (c.tracked.to_bits(), c.effort.to_bits());
            let new = !seen.contains(&key);
            seen.push(key);
            new
        });
        Self {
            runs: t.runs.iter().map(|r| r.name.clone()).collect(),
            arm: t.runs.first().and_then(|r| r.spatial.as_ref()).map(|s| s.arm.name().to_string()),
            space: t.space.clone(),
            effort_weight: t.effort_weight,
            seed: t.seed,
            starts: t.starts,
            tolerance: t.settle.tolerance,
            best,
            pareto: pareto.iter().map(|c| c.index).collect(),
            candidates,
        }
    }

    /// The best candidate.
    pub fn best(&self) -> Option<&Candidate> {
        self.best.map(|i| &self.candidates[i])
    }

    /// The best candidate as a `--config` file: the base's file with the knobs set, with a
    /// comment saying where it comes from.
    ///
    /// # Errors
    /// No valid candidate, or serialisation failed.
    pub fn preset(&self, t: &Tuning) -> Result<String, ReportError> {
        let best = self.best().ok_or(ReportError::NoValidCandidate)?;
        let r = &t.runs[0];
        let builder = knobs::apply(&r.builder, &r.base, &best.values);
        let mut file = builder.current_config().clone();
        // The limits that ran (the file's merged with --limits), so that the preset alone is
        // the tuned robot as it ran.
        if let Ok(s) = builder.build() {
            file.velocity_limits = s.controller.limits;
            file.acceleration_limits = s.controller.acceleration;
        }
        let mut text = format!(
            "# companion tune: the best of {} candidates on runs {} (seed {}):\n\
             # mean tracked fraction after 20 s {:.3}, mean rms |v| {:.3} m/s.\n",
            self.candidates.len(),
            self.runs.join(", "),
            self.seed,
            best.tracked,
            best.effort
        );
        if let Some(arm) = &self.arm {
            let _ = writeln!(
                text,
                "# runs of the spatial arm `{arm}`: use it with the same --arm and --config THIS_FILE"
            );
        }
        if !self.starts.is_home() {
            let _ = writeln!(
                text,
                "# each run from {} homes {} (seed {}); tracked: ‖e_p‖ < {:e} after 20 s",
                self.starts.count, self.starts.perturbation, self.starts.seed, self.tolerance
            );
        }
        for s in &best.runs {
            let _ = writeln!(
                text,
                "# {}: tracked {:.3}, settled from {} of {} starts, rms |v| {:.3} m/s, {} maneuvers",
                s.run, s.tracked, s.settled, s.starts, s.rms_v, s.maneuvers
            );
        }
        text.push_str(
            "# Use it with --config (the platform and the limits it was tuned for are the same flags).\n\n",
        );
        text.push_str(&toml::to_string(&file).map_err(ReportError::Preset)?);
        Ok(text)
    }

    /// Writes `preset.toml`, `report.json`, `candidates.csv` and `pareto.svg` into `out`.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn write(&self, out: &Path, t: &Tuning) -> Result<(), ReportError> {
        std::fs::write(out.join("preset.toml"), self.preset(t)?).map_err(writing("preset.toml"))?;
        std::fs::write(out.join("report.json"), serde_json::to_string_pretty(self)? + "\n")
            .map_err(writing("report.json"))?;
        let mut csv = String::from("index,stage");
        for (k, _) in &self.space {
            let _ = write!(csv, ",{}", k.name());
        }
        for r in &self.runs {
            let _ = write!(csv, ",tracked_{r},settled_{r},rms_v_{r},maneuvers_{r}");
        }
        csv.push_str(",tracked,settled,effort,cost,pareto,invalid\n");
        for c in &self.candidates {
            let _ = write!(csv, "{},{}", c.index, c.stage);
            for (_, v) in &c.values {
                let _ = write!(csv, ",{v}");
            }
            for r in &c.runs {
                let _ = write!(csv, ",{},{},{},{}", r.tracked, r.settled, r.rms_v, r.maneuvers);
            }
            if c.runs.is_empty() {
                csv.push_str(&",,,,".repeat(self.runs.len()));
            }
            let why = c.invalid.as_deref().unwrap_or("").replace([',', '\n'], ";");
            let _ = writeln!(
                csv,
                ",{},{},{},{},{},{why}",
                c.tracked,
                c.settled,
                c.effort,
                c.cost,
                self.pareto.contains(&c.index)
            );
        }
        std::fs::write(out.join("candidates.csv"), csv).map_err(writing("candidates.csv"))?;
        Ok(self.plot(&out.join("pareto.svg")).map_err(PlotError::plotting)?)
    }

    fn plot(&self, file: &Path) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let root = SVGBackend::new(file, (640, 440)).into_drawing_area();
        root.fill(&WHITE)?;
        let valid: Vec<&Candidate> = self.candidates.iter().filter(|c| c.cost.is_finite()).collect();
        let e_max = valid.iter().map(|c| c.effort).filter(|e| e.is_finite()).fold(0.1, f64::max) * 1.1;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("tune on {}: tracked fraction against effort", self.runs.join(", ")),
                ("sans-serif", 16),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..e_max, 0.0..1.02)?;
        chart
            .configure_mesh()
            .x_desc("mean rms |v| (m/s)")
            .y_desc("mean tracked fraction after 20 s")
            .draw()?;
        chart
            .draw_series(
                valid.iter().map(|c| Circle::new((c.effort, c.tracked), 2, RGBColor(150, 150, 150).filled())),
            )?
            .label("candidate")
            .legend(|(x, y)| Circle::new((x + 8, y), 3, RGBColor(150, 150, 150).filled()));
        let front: Vec<(f64, f64)> =
            self.pareto.iter().map(|&i| (self.candidates[i].effort, self.candidates[i].tracked)).collect();
        chart
            .draw_series(LineSeries::new(front.clone(), RGBColor(31, 119, 180).stroke_width(2)))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RGBColor(31, 119, 180)));
        chart.draw_series(front.iter().map(|p| Circle::new(*p, 3, RGBColor(31, 119, 180).filled())))?;
        if let Some(b) = self.best() {
            chart
                .draw_series([Cross::new((b.effort, b.tracked), 6, RGBColor(214, 39, 40).stroke_width(2))])?
                .label("best (the preset)")
                .legend(|(x, y)| Cross::new((x + 8, y), 4, RGBColor(214, 39, 40)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .border_style(BLACK)
            .background_style(WHITE)
            .draw()?;
        root.present()?;
        Ok(())
    }
}

/// Writes the report's files into `out`.
///
/// # Errors
/// A file cannot be written.
pub fn write(out: &Path, tuning: &Tuning, report: &TuneReport) -> Result<(), ReportError> {
    std::fs::create_dir_all(out).map_err(|source| ReportError::Folder { path: out.to_path_buf(), source })?;
    report.write(out, tuning)
}
