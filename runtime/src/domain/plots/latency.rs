//! Latency figures (SVG): a histogram on log-log axes and the percentile spectrum, where the
//! tail — what a deadline cares about — is as visible as the median.

use std::path::Path;

use plotters::prelude::*;

use super::error::PlotError;
use crate::domain::histogram::LatencyHistogram;
use crate::domain::spread::Spread;

const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// Bins per decade of the histogram panel.
const BINS_PER_DECADE: f64 = 20.0;

fn e<E: std::fmt::Debug>(err: E) -> PlotError {
    PlotError::Draw { what: "drawing", detail: format!("{err:?}") }
}

/// `(bin centre µs, count)` of log-spaced bins.
fn log_bins(h: &LatencyHistogram) -> Vec<(f64, f64)> {
    let mut bins: std::collections::BTreeMap<i64, u64> = std::collections::BTreeMap::new();
    for (v, c) in h.buckets() {
        let k = ((v.max(1) as f64).log10() * BINS_PER_DECADE).floor() as i64;
        *bins.entry(k).or_default() += c;
    }
    bins.into_iter().map(|(k, c)| (10f64.powf((k as f64 + 0.5) / BINS_PER_DECADE) / 1e3, c as f64)).collect()
}

/// `(nines, µs)`: the value at quantile `1 − 10^(−nines)`, up to the resolution of the sample.
fn spectrum(h: &LatencyHistogram) -> Vec<(f64, f64)> {
    let top = (h.count().max(1) as f64).log10();
    let mut out = Vec::new();
    let mut x = 0.0;
    while x <= top + 1e-9 {
        let q = 1.0 - 10f64.powf(-x);
        out.push((x, h.quantile(q).max(1) as f64 / 1e3));
        x += 0.05;
    }
    out.push((top, h.quantile(1.0).max(1) as f64 / 1e3));
    out
}

/// Draws `series` (name, histogram in ns) into `path`; `deadline_ns` is drawn as a line.
///
/// # Errors
/// The file cannot be written.
pub fn latency_svg(
    path: &Path,
    title: &str,
    series: &[(&str, &LatencyHistogram)],
    deadline_ns: Option<u64>,
) -> Result<(), PlotError> {
    let root = SVGBackend::new(path, (1000, 820)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    let (upper, lower) = root.split_vertically(390);
    let nonempty: Vec<_> = series.iter().filter(|(_, h)| h.count() > 0).collect();
    let max_us = nonempty
        .iter()
        .map(|(_, h)| h.quantile(1.0) as f64 / 1e3)
        .fold(deadline_ns.map_or(1.0, |d| d as f64 / 1e3), f64::max)
        * 1.5;
    let min_us =
        nonempty.iter().map(|(_, h)| h.percentiles().min.max(1) as f64 / 1e3).fold(f64::INFINITY, f64::min);
    let min_us = if min_us.is_finite() { (min_us / 1.5).max(0.01) } else { 0.01 };
    let max_count = nonempty.iter().flat_map(|(_, h)| log_bins(h)).map(|(_, c)| c).fold(10.0, f64::max) * 2.0;

    let mut hist = ChartBuilder::on(&upper)
        .caption("histogram (log-spaced bins, 20 per decade)", ("sans-serif", 15))
        .margin(12)
        .x_label_area_size(38)
        .y_label_area_size(60)
        .build_cartesian_2d((min_us..max_us).log_scale(), (0.8f64..max_count).log_scale())
        .map_err(e)?;
    hist.configure_mesh()
        .x_desc("latency (µs)")
        .y_desc("samples")
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(e)?;
    for (i, (name, h)) in nonempty.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        hist.draw_series(LineSeries::new(log_bins(h), c.stroke_width(2)))
            .map_err(e)?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
    }
    if let Some(d) = deadline_ns {
        let d = d as f64 / 1e3;
        hist.draw_series(LineSeries::new(vec![(d, 0.8), (d, max_count)], BLACK.mix(0.6).stroke_width(1)))
            .map_err(e)?
            .label("deadline")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.6)));
    }
    hist.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw().map_err(e)?;

    let max_nines = nonempty.iter().map(|(_, h)| (h.count().max(1) as f64).log10()).fold(1.0, f64::max);
    let mut spec = ChartBuilder::on(&lower)
        .caption(
            "percentile spectrum (x = number of nines: 1 → p90, 2 → p99, 4 → p99.99)",
            ("sans-serif", 15),
        )
        .margin(12)
        .x_label_area_size(38)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..max_nines.ceil(), (min_us..max_us).log_scale())
        .map_err(e)?;
    let ticks = max_nines.ceil() as usize + 1;
    spec.configure_mesh()
        .x_labels(ticks)
        .x_desc("percentile (nines)")
        .y_desc("latency (µs)")
        .x_label_formatter(&|x| {
            let q = 100.0 * (1.0 - 10f64.powf(-x));
            if *x < 0.5 {
                "p0".to_string()
            } else {
                format!("p{}", format!("{q:.4}").trim_end_matches('0').trim_end_matches('.'))
            }
        })
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(e)?;
    for (i, (name, h)) in nonempty.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        spec.draw_series(LineSeries::new(spectrum(h), c.stroke_width(2)))
            .map_err(e)?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
    }
    if let Some(d) = deadline_ns {
        let d = d as f64 / 1e3;
        spec.draw_series(LineSeries::new(
            vec![(0.0, d), (max_nines.ceil(), d)],
            BLACK.mix(0.6).stroke_width(1),
        ))
        .map_err(e)?;
    }
    spec.configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// One box of [`boxes_svg`]: its label and the values it summarises (one per run).
#[derive(Clone, Copy, Debug)]
pub struct BoxSeries<'a> {
    /// Under the box.
    pub label: &'a str,
    /// The runs' values.
    pub values: &'a [f64],
}

/// One panel of [`boxes_svg`].
#[derive(Clone, Debug)]
pub struct BoxPanel<'a> {
    /// Its title.
    pub title: String,
    /// The y axis's description.
    pub y_desc: &'a str,
    /// Its boxes, left to right.
    pub boxes: Vec<BoxSeries<'a>>,
}

/// Draws `panels` (`columns` to a row) into `path`: per box the interquartile range, the
/// median as a thick line, whiskers to the best and worst run, and every run as a dot —
/// a box per wait mode and load of `companion latency --repeat`.
///
/// # Errors
/// The file cannot be written.
pub fn boxes_svg(path: &Path, title: &str, panels: &[BoxPanel<'_>], columns: usize) -> Result<(), PlotError> {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let root = SVGBackend::new(path, (640 * columns as u32, 330 * rows as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let body = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    let areas = body.split_evenly((rows, columns));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let spreads: Vec<Option<Spread>> = panel.boxes.iter().map(|b| Spread::of(b.values)).collect();
        let (lo, hi) = spreads
            .iter()
            .flatten()
            .fold((0.0f64, f64::NEG_INFINITY), |(lo, hi), s| (lo.min(s.best), hi.max(s.worst)));
        let hi = if hi.is_finite() && hi > lo { hi } else { lo + 1.0 };
        let pad = 0.08 * (hi - lo);
        let n = panel.boxes.len().max(1) as f64;
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5f64..n - 0.5, (lo - if lo < 0.0 { pad } else { 0.0 })..hi + pad)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_desc(panel.y_desc)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(e)?;
        for (i, (b, s)) in panel.boxes.iter().zip(&spreads).enumerate() {
            let c = COLORS[i % COLORS.len()];
            let x = i as f64;
            let (px, py) = chart.backend_coord(&(x, lo - if lo < 0.0 { pad } else { 0.0 }));
            root.draw(&Text::new(
                b.label.to_string(),
                (px, py + 6),
                ("sans-serif", 12).into_font().color(&BLACK).pos(plotters::style::text_anchor::Pos::new(
                    plotters::style::text_anchor::HPos::Center,
                    plotters::style::text_anchor::VPos::Top,
                )),
            ))
            .map_err(e)?;
            let Some(s) = s else { continue };
            let w = 0.28;
            chart
                .draw_series([
                    Rectangle::new([(x - w, s.q1), (x + w, s.q3)], c.mix(0.25).filled()),
                    Rectangle::new([(x - w, s.q1), (x + w, s.q3)], c.stroke_width(1)),
                ])
                .map_err(e)?;
            let lines = [
                vec![(x - w, s.median), (x + w, s.median)],
                vec![(x, s.q3), (x, s.worst)],
                vec![(x, s.q1), (x, s.best)],
                vec![(x - w / 2.0, s.worst), (x + w / 2.0, s.worst)],
                vec![(x - w / 2.0, s.best), (x + w / 2.0, s.best)],
            ];
            for (k, l) in lines.into_iter().enumerate() {
                chart
                    .draw_series(LineSeries::new(l, c.stroke_width(if k == 0 { 3 } else { 1 })))
                    .map_err(e)?;
            }
            chart
                .draw_series(b.values.iter().map(|v| Circle::new((x + w + 0.06, *v), 2, c.filled())))
                .map_err(e)?;
        }
    }
    root.present().map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_a_box_per_series_with_its_label() {
        let dir = std::env::temp_dir().join(format!("companion-boxes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("b.svg");
        let a = [3.0, 7.0, 1.0, 12.0];
        let panels = [
            BoxPanel {
                title: "misses, idle".into(),
                y_desc: "misses per run",
                boxes: vec![
                    BoxSeries { label: "event", values: &a },
                    BoxSeries { label: "bare iceoryx2", values: &[-2.0, 0.0] },
                ],
            },
            BoxPanel {
                title: "nothing yet".into(),
                y_desc: "µs",
                boxes: vec![BoxSeries { label: "spin", values: &[] }],
            },
        ];
        boxes_svg(&p, "test", &panels, 2).unwrap();
        let s = std::fs::read_to_string(&p).unwrap();
        assert!(s.starts_with("<svg"));
        for text in ["misses, idle", "event", "bare iceoryx2", "nothing yet", "spin"] {
            assert!(s.contains(text), "{text} missing");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn draws_an_svg() {
        let mut a = LatencyHistogram::new();
        let mut b = LatencyHistogram::new();
        for i in 0..10_000u64 {
            a.record(2_000 + (i % 100) * 10);
            b.record(10_000 + (i % 1000) * 37);
        }
        let dir = std::env::temp_dir().join(format!("companion-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("l.svg");
        latency_svg(&p, "test", &[("a", &a), ("b", &b), ("empty", &LatencyHistogram::new())], Some(500_000))
            .unwrap();
        let s = std::fs::read_to_string(&p).unwrap();
        assert!(s.starts_with("<svg") && s.contains("deadline"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
