//! Figures a person would rather look at than read: SVG plots of a run and, for
//! `sim --all`, an index page laid out like the paper's Figures 3–10 ((a)–(d) side by side).
//!
//! Per run: `path.svg` (Cartesian paths of platform, end effector and target, with the robot
//! drawn at intervals), `ep.svg` (‖e_p‖ on a log axis), `velocities.svg` (v and ω),
//! `hs.svg` (h_s on a log axis), `joints.svg` (each joint against its limits).

use std::fmt::Write as _;
use std::path::Path;

use companion_core::Params;
use plotters::coord::Shift;
use plotters::prelude::*;

use companion_core::{PaperRun, PlatformCommand, PlatformKind, Space};
use companion_plant::PaperTrajectory;

pub use self::error::PlotError;
pub use self::latency::latency_svg;
use crate::domain::controller::run_name;
use crate::domain::record::{Row, RunOutcome};
use crate::domain::scenario::Target;

mod error;
mod latency;
pub mod spatial;

const W: u32 = 640;
const H: u32 = 400;
const BASE: RGBColor = RGBColor(90, 90, 90);
const EFFECTOR: RGBColor = RGBColor(31, 119, 180);
const TARGET: RGBColor = RGBColor(214, 39, 40);
const ARM: RGBColor = RGBColor(44, 160, 44);
const SECOND: RGBColor = RGBColor(255, 127, 14);

/// The result of writing figures.
type Result<T, E = PlotError> = std::result::Result<T, E>;

/// The file names of the per-run figures, in display order, with their titles.
pub const FIGURES: [(&str, &str); 5] = [
    ("path.svg", "Cartesian paths"),
    ("ep.svg", "tracking error ‖e_p‖"),
    ("velocities.svg", "platform velocities"),
    ("hs.svg", "secondary cost h_s"),
    ("joints.svg", "joints and their limits"),
];

/// Renders the figures of one run into `dir`, and an `index.html` showing them.
///
/// # Errors
/// Writing a file failed.
pub fn render_run(dir: &Path, run: &RunOutcome) -> Result<()> {
    render_figures(dir, run)?;
    let mut html = page_head(&run.scenario.name);
    let _ = write!(html, "<h1>{}</h1>\n{}\n<div class=grid>", run.scenario.name, summary_table(&[run]));
    for (file, title) in FIGURES {
        let _ = write!(html, "<figure><img src=\"{file}\"><figcaption>{title}</figcaption></figure>");
    }
    html.push_str("</div></body></html>\n");
    std::fs::write(dir.join("index.html"), html).map_err(PlotError::Index)
}

/// Renders every run's figures into `dir/<name>/` and an index page `dir/index.html` laid
/// out like the paper's Figures 3–10.
///
/// # Errors
/// Writing a file failed.
pub fn render_all(dir: &Path, runs: &[RunOutcome]) -> Result<()> {
    use rayon::prelude::*;
    runs.par_iter().try_for_each(|r| render_figures(&dir.join(&r.scenario.name), r))?;
    let mut html = page_head("companion: the paper's runs");
    html.push_str(
        "<h1>The paper's simulations, reproduced</h1>\
         <p>Unicycle platform with the RPR arm, §4.3 parameters, dt as run. Columns (a)–(d) are the \
         paper's control variants; rows follow the paper's Figures 3–6 (trajectory 1) and 7–10 \
         (trajectory 2). Each image links to its run's folder (CSV, JSON, all figures).</p>",
    );
    let find = |traj: PaperTrajectory, choice: PaperRun, platform: PlatformKind, psidot: bool| {
        runs.iter().find(|r| {
            let c = &r.scenario.controller;
            r.scenario.target == Target::Paper(traj)
                && c.choice == choice
                && c.platform == platform
                && (c.overrides.psi_rate_in_drift == Some(true)) == psidot
        })
    };
    let choices = [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D];
    for (traj, n, first_fig) in [(PaperTrajectory::One, 1, 3u8), (PaperTrajectory::Two, 2, 7)] {
        let _ = write!(html, "<h2>Trajectory {n}</h2>");
        for (k, (file, title)) in FIGURES.iter().take(4).enumerate() {
            let _ = write!(html, "<h3>Figure {} — {title}</h3><div class=row>", first_fig as usize + k);
            for c in choices {
                if let Some(r) = find(traj, c, PlatformKind::Unicycle, false) {
                    let n = &r.scenario.name;
                    let _ = write!(
                        html,
                        "<figure><a href=\"{n}/index.html\"><img src=\"{n}/{file}\"></a><figcaption>({})</figcaption></figure>",
                        run_name(c)
                    );
                }
            }
            html.push_str("</div>");
        }
    }
    html.push_str("<h2>With the Ψ̇ term in the drift (runs b and d)</h2><p>SPEC §3: with it, b and d chatter.</p><div class=row>");
    for traj in [PaperTrajectory::One, PaperTrajectory::Two] {
        for c in [PaperRun::B, PaperRun::D] {
            for psidot in [false, true] {
                if let Some(r) = find(traj, c, PlatformKind::Unicycle, psidot) {
                    let n = &r.scenario.name;
                    let _ = write!(
                        html,
                        "<figure><a href=\"{n}/index.html\"><img src=\"{n}/velocities.svg\"></a><figcaption>{n}</figcaption></figure>"
                    );
                }
            }
        }
    }
    html.push_str("</div><h2>Car-like and omnidirectional platforms</h2><div class=row>");
    for r in runs.iter().filter(|r| r.scenario.controller.platform != PlatformKind::Unicycle) {
        let n = &r.scenario.name;
        let _ = write!(
            html,
            "<figure><a href=\"{n}/index.html\"><img src=\"{n}/path.svg\"></a><figcaption>{n}</figcaption></figure>"
        );
    }
    html.push_str("</div><h2>Summaries</h2>");
    let refs: Vec<&RunOutcome> = runs.iter().collect();
    html.push_str(&summary_table(&refs));
    html.push_str("</body></html>\n");
    std::fs::write(dir.join("index.html"), html).map_err(PlotError::Index)
}

fn page_head(title: &str) -> String {
    format!(
        "<!doctype html><html><head><meta charset=utf-8><title>{title}</title><style>\
         body{{font-family:sans-serif;margin:1em}} .row,.grid{{display:flex;flex-wrap:wrap}} \
         figure{{margin:4px}} img{{width:420px}} table{{border-collapse:collapse;font-size:13px}} \
         td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}</style></head><body>"
    )
}

/// `x` formatted, or "n/a" for a figure the run has no data for (NaN: no step after 20 s).
fn or_na(x: f64, f: impl Fn(f64) -> String) -> String {
    if x.is_nan() {
        "n/a".to_owned()
    } else {
        f(x)
    }
}

fn summary_table(runs: &[&RunOutcome]) -> String {
    let mut t = String::from(
        "<table><tr><th>run</th><th>final ‖e_p‖</th><th>max ‖e_p‖ t≥20 s</th><th>tracked t≥20 s</th>\
         <th>path (m)</th><th>v sign changes</th><th>max |v|</th><th>max |ω|</th><th>min joint margins</th></tr>",
    );
    for r in runs {
        let s = &r.summary;
        let _ = write!(
            t,
            "<tr><td>{}</td><td>{:.2e}</td><td>{}</td><td>{}</td><td>{:.2}</td><td>{}</td>\
             <td>{:.3}</td><td>{:.3}</td><td>{:.4} {:.4} {:.4}</td></tr>",
            s.scenario,
            s.final_ep_norm,
            or_na(s.max_ep_norm_after_20s, |x| format!("{x:.2e}")),
            or_na(s.fraction_ep_below_1e_3_after_20s, |x| format!("{:.1} %", 100.0 * x)),
            s.path_length,
            s.v_sign_changes,
            s.max_abs_v,
            s.max_abs_omega,
            s.min_joint_margin[0],
            s.min_joint_margin[1],
            s.min_joint_margin[2]
        );
    }
    t.push_str("</table>");
    t
}

fn render_figures(dir: &Path, run: &RunOutcome) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Folder { path: dir.to_path_buf(), source })?;
    let rows = &run.rows;
    if rows.is_empty() {
        return Ok(());
    }
    let name = &run.scenario.name;
    path_plot(&dir.join("path.svg"), name, rows).map_err(PlotError::plotting)?;
    log_plot(&dir.join("ep.svg"), &format!("{name}: ‖e_p‖"), rows, |r| r.plant.ep_norm)
        .map_err(PlotError::plotting)?;
    log_plot(&dir.join("hs.svg"), &format!("{name}: h_s"), rows, |r| r.report.h_s)
        .map_err(PlotError::plotting)?;
    velocity_plot(
        &dir.join("velocities.svg"),
        name,
        rows,
        &planar_velocities(run.scenario.controller.platform),
    )
    .map_err(PlotError::plotting)?;
    joints_plot(&dir.join("joints.svg"), name, rows).map_err(PlotError::plotting)?;
    Ok(())
}

/// Square ranges around the finite `xs` and `ys`: equal scales on both axes (a map view).
fn equal_scale(
    xs: impl Iterator<Item = f64>,
    ys: impl Iterator<Item = f64>,
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (x0, x1) = bounds(xs);
    let (y0, y1) = bounds(ys);
    let span = (x1 - x0).max(y1 - y0);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    (cx - span / 2.0..cx + span / 2.0, cy - span / 2.0..cy + span / 2.0)
}

fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;

fn path_plot(file: &Path, name: &str, rows: &[Row]) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let root: Area<'_> = SVGBackend::new(file, (W, W)).into_drawing_area();
    root.fill(&WHITE)?;
    let xs = rows.iter().flat_map(|r| [r.plant.base.x, r.plant.end_effector.x, r.plant.target.x]);
    let ys = rows.iter().flat_map(|r| [r.plant.base.y, r.plant.end_effector.y, r.plant.target.y]);
    let (xr, yr) = equal_scale(xs, ys);
    let mut chart = ChartBuilder::on(&root)
        // The effector does not sit on the target: the task holds the target at X* in the
        // effector's frame (0.5 m ahead in the paper), so the two paths run apart by design.
        .caption(
            format!("{name}: paths (the target held at X*, 0.5 m ahead in the paper)"),
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(xr, yr)?;
    chart.configure_mesh().x_desc("x (m)").y_desc("y (m)").draw()?;
    // The robot at intervals: platform as an oriented triangle, arm as links.
    let every = (rows.len() / 12).max(1);
    let arm = companion_core::Rpr::<f64>::paper();
    for r in rows.iter().step_by(every) {
        let b = &r.plant.base;
        let (s, c) = b.theta.sin_cos();
        let at = |x: f64, y: f64| (b.x + c * x - s * y, b.y + s * x + c * y);
        let tri = vec![at(0.25, 0.0), at(-0.15, 0.12), at(-0.15, -0.12), at(0.25, 0.0)];
        chart.draw_series(std::iter::once(PathElement::new(tri, BASE.mix(0.6).stroke_width(1))))?;
        let q = &r.plant.joints;
        let (s1, c1) = q[0].sin_cos();
        let j1 = at(arm.l, 0.0);
        let j2 = at(arm.l + q[1] * c1, q[1] * s1);
        let e = (r.plant.end_effector.x, r.plant.end_effector.y);
        chart.draw_series(std::iter::once(PathElement::new(
            vec![at(0.0, 0.0), j1, j2, e],
            ARM.stroke_width(1),
        )))?;
    }
    chart
        .draw_series(LineSeries::new(
            rows.iter().map(|r| (r.plant.base.x, r.plant.base.y)),
            BASE.stroke_width(2),
        ))?
        .label("platform")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BASE.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            rows.iter().map(|r| (r.plant.end_effector.x, r.plant.end_effector.y)),
            EFFECTOR.stroke_width(1),
        ))?
        .label("end effector")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], EFFECTOR));
    chart
        .draw_series(LineSeries::new(
            rows.iter().map(|r| (r.plant.target.x, r.plant.target.y)),
            TARGET.stroke_width(1),
        ))?
        .label("target")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], TARGET));
    chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}

fn log_plot(
    file: &Path,
    title: &str,
    rows: &[Row],
    f: impl Fn(&Row) -> f64,
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.plant.t, f(r))).collect();
    let t1 = rows.last().map_or(1.0, |r| r.plant.t);
    log_lines(file, title, t1, &[("", EFFECTOR, pts)])
}

/// A labelled curve: `(label, colour, points)`.
type Curve<'a> = (&'a str, RGBColor, Vec<(f64, f64)>);

/// Curves `(label, colour, (t, value))` on a log axis against time up to `t1`, values below
/// 1e−12 drawn at 1e−12, non-finite ones left out; a legend when a label is given.
fn log_lines(
    file: &Path,
    title: &str,
    t1: f64,
    series: &[Curve<'_>],
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let root: Area<'_> = SVGBackend::new(file, (W, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let floor = 1e-12;
    let clean = |pts: &[(f64, f64)]| -> Vec<(f64, f64)> {
        pts.iter().filter(|p| p.1.is_finite()).map(|&(t, v)| (t, v.max(floor))).collect()
    };
    let series: Vec<Curve<'_>> = series.iter().map(|(l, c, p)| (*l, *c, clean(p))).collect();
    let all = || series.iter().flat_map(|s| s.2.iter().map(|p| p.1));
    let hi = all().fold(floor, f64::max) * 3.0;
    let lo = all().fold(f64::INFINITY, f64::min).max(floor) / 3.0;
    let t1 = t1.max(1e-3);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..t1, (lo.min(hi / 10.0)..hi).log_scale())?;
    chart.configure_mesh().x_desc("t (s)").y_label_formatter(&|v| format!("{v:.0e}")).draw()?;
    for (label, colour, pts) in series.iter().cloned() {
        let drawn = chart.draw_series(LineSeries::new(pts, colour.stroke_width(1)))?;
        if !label.is_empty() {
            drawn.label(label).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        }
    }
    if series.iter().any(|s| !s.0.is_empty()) {
        chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    }
    root.present()?;
    Ok(())
}

/// A platform velocity drawn against time: its label, colour and component.
pub(crate) type VelocitySeries = (&'static str, RGBColor, fn(&PlatformCommand<f64>) -> f64);

/// The paper's platform velocities of `platform`: `v` and `ω` (the car's `v_ξ`), and the
/// omnidirectional platform's `v_lat`.
fn planar_velocities(platform: PlatformKind) -> Vec<VelocitySeries> {
    let mut series: Vec<VelocitySeries> = vec![("v (m/s)", EFFECTOR, |c| c.v)];
    series.push(match platform {
        PlatformKind::Car => ("v_ξ (1/(m·s))", SECOND, |c| c.v_xi),
        PlatformKind::Unicycle | PlatformKind::Omni => ("ω (rad/s)", SECOND, |c| c.omega),
    });
    if platform == PlatformKind::Omni {
        series.push(("v_lat (m/s)", ARM, |c| c.v_lat));
    }
    series
}

/// The platform velocities commanded over a run of either arm: each of `series`.
pub(crate) fn velocity_plot<S: Space<f64>, const N: usize>(
    file: &Path,
    name: &str,
    rows: &[Row<S, N>],
    series: &[VelocitySeries],
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let root: Area<'_> = SVGBackend::new(file, (W, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let command = |r: &Row<S, N>| r.report.command.platform;
    let (y0, y1) = bounds(rows.iter().flat_map(|r| series.iter().map(move |s| s.2(&command(r)))));
    let t1 = rows.last().map_or(1.0, |r| r.plant.t).max(1e-3);
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{name}: platform velocities"), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(0.0..t1, y0..y1)?;
    chart.configure_mesh().x_desc("t (s)").draw()?;
    for &(label, colour, f) in series {
        chart
            .draw_series(LineSeries::new(
                rows.iter().map(|r| (r.plant.t, f(&command(r)))),
                colour.stroke_width(1),
            ))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}

fn joints_plot(
    file: &Path,
    name: &str,
    rows: &[Row],
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let root: Area<'_> = SVGBackend::new(file, (W, H + 200)).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(30);
    title.titled(&format!("{name}: joints and their limits"), ("sans-serif", 18))?;
    let limits = Params::<f64, 3>::paper_limits();
    let t1 = rows.last().map_or(1.0, |r| r.plant.t).max(1e-3);
    let names = ["q₁ (rad)", "q₂ (m)", "q₃ (rad)"];
    for (i, area) in body.split_evenly((3, 1)).iter().enumerate() {
        let (lo, hi) = (limits.lower[i], limits.upper[i]);
        let pad = 0.05 * (hi - lo);
        let mut chart = ChartBuilder::on(area)
            .margin(6)
            .x_label_area_size(if i == 2 { 30 } else { 12 })
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..t1, lo - pad..hi + pad)?;
        chart.configure_mesh().y_desc(names[i]).max_light_lines(2).draw()?;
        for l in [lo, hi] {
            chart.draw_series(LineSeries::new(vec![(0.0, l), (t1, l)], TARGET.stroke_width(1)))?;
        }
        chart.draw_series(LineSeries::new(rows.iter().map(|r| (r.plant.t, r.plant.joints[i])), EFFECTOR))?;
    }
    root.present()?;
    Ok(())
}

/// One curve of [`floor_plot`]: its label, whether it is the default discretisation (solid)
/// or the sampled one (dashed), and its `(period, floor)` points.
#[derive(Clone, Debug)]
pub struct FloorCurve {
    /// The legend's text.
    pub label: String,
    /// Drawn solid (the default) or dashed (the sampled law).
    pub solid: bool,
    /// `(period s, floor m)`.
    pub points: Vec<(f64, f64)>,
}

/// The tracking floor against the control period, log-log, with the slopes 1 and 2 for
/// reference: the figure of docs/book/src/precision.md.
///
/// # Errors
/// The file cannot be written.
pub fn floor_plot(file: &Path, curves: &[FloorCurve]) -> Result<()> {
    floor_plot_inner(file, curves).map_err(|source| PlotError::Figure { path: file.to_path_buf(), source })
}

fn floor_plot_inner(
    file: &Path,
    curves: &[FloorCurve],
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let root: Area<'_> = SVGBackend::new(file, (W, H + 80)).into_drawing_area();
    root.fill(&WHITE)?;
    let all = curves.iter().flat_map(|c| c.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for (x, y) in all {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    let mut chart = ChartBuilder::on(&root)
        .caption("tracking floor against the control period", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d((x0 / 1.3..x1 * 1.3).log_scale(), (y0 / 3.0..y1 * 3.0).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("control period (ms)")
        .y_desc("max ‖e_p‖ after 20 s (m)")
        .x_labels(6)
        .x_label_formatter(&|v| format!("{}", v * 1e3))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    let palette = [EFFECTOR, TARGET, ARM, SECOND, BASE];
    for (i, c) in curves.iter().enumerate() {
        let color = palette[(i / 2) % palette.len()];
        let style = color.stroke_width(if c.solid { 2 } else { 1 });
        let pts = c.points.clone();
        if c.solid {
            chart
                .draw_series(LineSeries::new(pts.clone(), style))?
                .label(c.label.clone())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], color.stroke_width(2)));
        } else {
            chart
                .draw_series(DashedLineSeries::new(pts.clone(), 6, 4, style))?
                .label(c.label.clone())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], color.stroke_width(1)));
        }
        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()?;
    root.present()?;
    Ok(())
}
