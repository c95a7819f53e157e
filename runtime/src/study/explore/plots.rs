//! The figures of an exploration (SVG): the success map, histograms of the settling time,
//! the tracked fraction and the smallest joint margin, and the observed bound on `‖e_p‖`
//! against the transverse function's size; and `index.html` showing them.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use super::results::{Class, Record};
use super::summary::{input_index, ExploreSummary};
use crate::domain::plots::PlotError;
use crate::study::knobs::Knob;

type Plot = Result<(), Box<dyn std::error::Error + Send + Sync>>;

const W: u32 = 640;
const H: u32 = 440;

/// The figure files, with their captions.
pub const FIGURES: [(&str, &str); 5] = [
    ("map.svg", "success map: fraction of samples that converge per cell"),
    ("settling.svg", "settling time of the converged samples"),
    ("tracked.svg", "tracked fraction over the second half of each run"),
    ("margin.svg", "smallest joint margin of each run"),
    (
        "ep_bound.svg",
        "largest ‖e_p‖ over the second half of each run, against the transverse function's size",
    ),
];

/// Writes the figures and `index.html` into `dir`.
///
/// # Errors
/// Writing a file failed.
pub fn render(
    dir: &Path,
    summary: &ExploreSummary,
    records: &[Record],
    knobs: &[Knob],
) -> Result<(), PlotError> {
    map(&dir.join("map.svg"), summary).map_err(PlotError::plotting)?;
    let col = |name: &str, only: Option<Class>| -> Vec<f64> {
        records
            .iter()
            .filter(|r| only.is_none_or(|c| r.class == c))
            .map(|r| r.outcome(name))
            .filter(|v| v.is_finite())
            .collect()
    };
    histogram(
        &dir.join("settling.svg"),
        "settling time (s), converged samples",
        &col("settling_time_s", Some(Class::Converged)),
    )
    .map_err(PlotError::plotting)?;
    histogram(&dir.join("tracked.svg"), "tracked fraction, t ≥ T/2", &col("tracked_fraction", None))
        .map_err(PlotError::plotting)?;
    histogram(&dir.join("margin.svg"), "smallest joint margin (rad or m)", &col("min_joint_margin", None))
        .map_err(PlotError::plotting)?;
    bound(&dir.join("ep_bound.svg"), summary, records, knobs).map_err(PlotError::plotting)?;
    let mut html = String::from(
        "<!doctype html><html><head><meta charset=utf-8><title>exploration</title><style>\
         body{font-family:sans-serif;margin:1em} .grid{display:flex;flex-wrap:wrap} figure{margin:4px} \
         img{width:480px} td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>",
    );
    let c = &summary.counts;
    let _ = write!(
        html,
        "<h1>Exploration of {}</h1><p>{} samples (seed {}): {} converged ({:.1} %), {} not converged, \
         {} diverged, {} rejected, {} invalid. Rows in <a href=results.csv>results.csv</a>, figures in \
         <a href=summary.json>summary.json</a>.</p><div class=grid>",
        summary.scenario,
        summary.samples,
        summary.seed,
        c.converged,
        100.0 * summary.converged_fraction,
        c.not_converged,
        c.diverged,
        c.rejected,
        c.invalid
    );
    for (file, caption) in FIGURES {
        let _ = write!(html, "<figure><img src=\"{file}\"><figcaption>{caption}</figcaption></figure>");
    }
    html.push_str("</div></body></html>\n");
    std::fs::write(dir.join("index.html"), html).map_err(PlotError::Index)
}

fn map(file: &Path, s: &ExploreSummary) -> Plot {
    let root = SVGBackend::new(file, (W, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let m = &s.map;
    let (x0, x1) = (m.x_edges[0], m.x_edges[m.x_edges.len() - 1]);
    let (y0, y1) = (m.y_edges[0], m.y_edges[m.y_edges.len() - 1]);
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{}: converged fraction", s.scenario), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart.configure_mesh().disable_mesh().x_desc(m.x.as_str()).y_desc(m.y.as_deref().unwrap_or("")).draw()?;
    for (j, row) in m.samples.iter().enumerate() {
        for (i, &n) in row.iter().enumerate() {
            let rect = [(m.x_edges[i], m.y_edges[j]), (m.x_edges[i + 1], m.y_edges[j + 1])];
            if n == 0 {
                chart.draw_series([Rectangle::new(rect, RGBColor(235, 235, 235).filled())])?;
                continue;
            }
            let f = m.converged[j][i] as f64 / n as f64;
            // Red (none converge) to green (all converge).
            let colour = RGBColor((220.0 * (1.0 - f)) as u8 + 20, (180.0 * f) as u8 + 40, 60);
            chart.draw_series([Rectangle::new(rect, colour.filled())])?;
            let centre = (0.5 * (rect[0].0 + rect[1].0), 0.5 * (rect[0].1 + rect[1].1));
            chart.draw_series([Text::new(
                format!("{:.0}", 100.0 * f),
                centre,
                ("sans-serif", 11).into_font().color(&WHITE).pos(plotters::style::text_anchor::Pos::new(
                    plotters::style::text_anchor::HPos::Center,
                    plotters::style::text_anchor::VPos::Center,
                )),
            )])?;
        }
    }
    root.present()?;
    Ok(())
}

fn histogram(file: &Path, title: &str, values: &[f64]) -> Plot {
    let root = SVGBackend::new(file, (W, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let (mut lo, mut hi) =
        values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    if hi - lo < 1e-12 {
        (lo, hi) = (lo - 0.5, hi + 0.5);
    }
    let bins = 30usize;
    let mut counts = vec![0u32; bins];
    for v in values {
        let i = (((v - lo) / (hi - lo)) * bins as f64).floor() as usize;
        counts[i.min(bins - 1)] += 1;
    }
    let top = counts.iter().copied().max().unwrap_or(1).max(1);
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{title} ({} samples)", values.len()), ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(lo..hi, 0u32..top + top / 10 + 1)?;
    chart.configure_mesh().disable_x_mesh().y_desc("samples").draw()?;
    let width = (hi - lo) / bins as f64;
    chart.draw_series(counts.iter().enumerate().map(|(i, &c)| {
        let x = lo + width * i as f64;
        Rectangle::new([(x, 0), (x + width, c)], RGBColor(31, 119, 180).filled())
    }))?;
    root.present()?;
    Ok(())
}

fn bound(file: &Path, s: &ExploreSummary, records: &[Record], knobs: &[Knob]) -> Plot {
    let root = SVGBackend::new(file, (W, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let name = s.size.clone().unwrap_or_else(|| "size".into());
    let si = input_index(&name, knobs);
    let floor = 1e-12;
    let pts: Vec<(f64, f64)> = records
        .iter()
        .filter(|r| matches!(r.class, Class::Converged | Class::NotConverged))
        .filter_map(|r| Some((r.inputs[si?], r.outcome("ep_bound").max(floor))))
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect();
    let (mut x0, mut x1) =
        pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    if x1 - x0 < 1e-12 {
        (x0, x1) = (x0 * 0.8, x1 * 1.2 + 1e-3);
    }
    let hi = pts.iter().map(|p| p.1).fold(1e-6, f64::max) * 3.0;
    let lo = pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min).clamp(floor, hi / 10.0) / 3.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{}: max ‖e_p‖ for t ≥ T/2 against {name}", s.scenario), ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc(name.as_str())
        .y_desc("‖e_p‖")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    chart.draw_series(pts.iter().map(|p| Circle::new(*p, 2, RGBColor(31, 119, 180).filled())))?;
    let envelope: Vec<(f64, f64)> = s
        .ep_bound_by_size
        .iter()
        .filter(|b| b.max_ep_bound.is_finite())
        .map(|b| (0.5 * (b.epsilon_low + b.epsilon_high), b.max_ep_bound.max(floor)))
        .collect();
    chart
        .draw_series(LineSeries::new(envelope, RGBColor(214, 39, 40).stroke_width(2)))?
        .label("largest per bin")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RGBColor(214, 39, 40)));
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    root.present()?;
    Ok(())
}
