//! The figures of a spatial run (apart from the paper's figures of the planar arm, which the
//! paper lays out; the velocity figure is the one both draw): `top.svg` (x–y: platform, end effector and target paths,
//! the robot drawn at intervals), `side.svg` (x–z: the arm drawn at the same instants, the
//! target's and the end effector's heights), `ep.svg` (‖e_p‖ and the position and rotation
//! parts, log axis), `hs.svg`, `velocities.svg` and `joints.svg` (each joint against its
//! limits), and an `index.html` with the summary.

use std::fmt::Write as _;
use std::path::Path;

use companion_core::{Chain, Pose3, Spatial};
use plotters::prelude::*;

use super::error::PlotError;
use super::{
    bounds, equal_scale, log_lines, page_head, velocity_plot, Area, VelocitySeries, ARM, BASE, EFFECTOR, H,
    SECOND, TARGET, W,
};
use crate::domain::record::{Row, Summary};

type Plot = Result<(), Box<dyn std::error::Error + Send + Sync>>;
/// A point of a row in a view.
type View<const N: usize> = fn(&Row<Spatial, N>) -> (f64, f64);
/// A value of a row against time.
type Value<const N: usize> = fn(&Row<Spatial, N>) -> f64;

/// The figures, in display order, with their titles.
pub const FIGURES: [(&str, &str); 6] = [
    ("top.svg", "top view (x–y)"),
    ("side.svg", "side view (x–z)"),
    ("ep.svg", "tracking error e_p"),
    ("hs.svg", "secondary cost h_s"),
    ("velocities.svg", "platform velocities"),
    ("joints.svg", "joints and their limits"),
];

/// What a spatial run's figures are drawn from: its rows, summary and arm.
#[derive(Clone, Copy, Debug)]
pub struct SpatialFigures<'a, const N: usize> {
    /// The run's name (the figures' titles).
    pub name: &'a str,
    /// The logged steps.
    pub rows: &'a [Row<Spatial, N>],
    /// The run's figures.
    pub summary: &'a Summary,
    /// The arm (its links drawn, its joints' limits).
    pub chain: &'a Chain<f64, N>,
}

/// Renders a spatial run's figures and `index.html` into `dir`.
///
/// # Errors
/// Writing a file failed.
pub fn render<const N: usize>(dir: &Path, run: &SpatialFigures<'_, N>) -> Result<(), PlotError> {
    let rows = run.rows;
    let chain = run.chain;
    let name = run.name;
    if !rows.is_empty() {
        top_view(&dir.join("top.svg"), name, rows, chain).map_err(PlotError::plotting)?;
        side_view(&dir.join("side.svg"), name, rows, chain).map_err(PlotError::plotting)?;
        let t1 = rows.last().map_or(1.0, |r| r.plant.t);
        let series = |f: Value<N>| rows.iter().map(|r| (r.plant.t, f(r))).collect::<Vec<_>>();
        log_lines(
            &dir.join("ep.svg"),
            &format!("{name}: e_p"),
            t1,
            &[
                ("‖e_p‖", EFFECTOR, series(|r| r.plant.ep_norm)),
                ("position ‖p̃‖ (m)", SECOND, series(|r| r.plant.e_p.fixed_rows::<3>(0).norm())),
                ("rotation ‖φ̃‖ (rad)", ARM, series(|r| r.plant.e_p.fixed_rows::<3>(3).norm())),
            ],
        )
        .map_err(PlotError::plotting)?;
        log_lines(
            &dir.join("hs.svg"),
            &format!("{name}: h_s"),
            t1,
            &[("", EFFECTOR, series(|r| r.report.h_s))],
        )
        .map_err(PlotError::plotting)?;
        velocities(&dir.join("velocities.svg"), name, rows).map_err(PlotError::plotting)?;
        joints(&dir.join("joints.svg"), name, rows, chain).map_err(PlotError::plotting)?;
    }
    let s = run.summary;
    let a = s.arm.clone().unwrap_or_default();
    let mut html = page_head(name);
    let _ = write!(
        html,
        "<h1>{name}</h1><table><tr><th>arm</th><th>final ‖e_p‖</th><th>max ‖e_p‖ t≥20 s</th><th>tracked t≥20 s</th>\
         <th>smallest joint margin</th><th>path (m)</th><th>rejected steps</th><th>verdict</th></tr>\
         <tr><td>{} ({} joints)</td><td>{:.2e}</td><td>{:.2e}</td><td>{:.1} %</td><td>{:.4} (joint {})</td><td>{:.2}</td><td>{}</td><td>{}</td></tr></table>\
         <div class=grid>",
        a.arm,
        a.joints,
        s.final_ep_norm,
        s.max_ep_norm_after_20s,
        100.0 * s.fraction_ep_below_1e_3_after_20s,
        a.smallest_joint_margin,
        a.smallest_margin_joint,
        s.path_length,
        s.rejected_steps,
        a.verdict,
    );
    for (file, title) in FIGURES {
        let _ = write!(html, "<figure><img src=\"{file}\"><figcaption>{title}</figcaption></figure>");
    }
    html.push_str("</div></body></html>\n");
    std::fs::write(dir.join("index.html"), html).map_err(PlotError::Index)
}

/// The arm as a polyline: platform origin, each link's origin after its joint's motion
/// (the chain's frames, `r_b · M · O₁ J₁(q₁) ⋯`), the end effector.
fn arm_points<const N: usize>(r: &Row<Spatial, N>, chain: &Chain<f64, N>) -> Vec<[f64; 3]> {
    let p = &r.plant;
    let world = Pose3::from_planar(&p.base);
    let mut pts = vec![[p.base.x, p.base.y, 0.0]];
    let mut f = chain.mount;
    for (j, q) in chain.joints.iter().zip(p.joints.iter()) {
        f = f.compose(&j.origin).compose(&j.motion(*q));
        let l = world.compose(&f).translation;
        pts.push([l[0], l[1], l[2]]);
    }
    let e = &p.end_effector.translation;
    pts.push([e[0], e[1], e[2]]);
    pts
}

/// Instants at which the robot is drawn: about 10, the last one included.
fn instants<const N: usize>(rows: &[Row<Spatial, N>]) -> impl Iterator<Item = &Row<Spatial, N>> {
    let every = (rows.len() / 10).max(1);
    rows.iter().step_by(every).chain(rows.last().filter(|_| (rows.len() - 1) % every != 0))
}

fn top_view<const N: usize>(
    file: &Path,
    name: &str,
    rows: &[Row<Spatial, N>],
    chain: &Chain<f64, N>,
) -> Plot {
    let root: Area<'_> = SVGBackend::new(file, (W, W)).into_drawing_area();
    root.fill(&WHITE)?;
    let p =
        |r: &Row<Spatial, N>| (r.plant.base, r.plant.end_effector.translation, r.plant.target.translation);
    let xs = rows.iter().map(p).flat_map(|(b, e, t)| [b.x, e[0], t[0]]);
    let ys = rows.iter().map(p).flat_map(|(b, e, t)| [b.y, e[1], t[1]]);
    let (xr, yr) = equal_scale(xs, ys);
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{name}: top view"), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(xr, yr)?;
    chart.configure_mesh().x_desc("x (m)").y_desc("y (m)").draw()?;
    for r in instants(rows) {
        let (x, y, th) = (r.plant.base.x, r.plant.base.y, r.plant.base.theta);
        let (s, c) = th.sin_cos();
        let at = |a: f64, b: f64| (x + c * a - s * b, y + s * a + c * b);
        let tri = vec![at(0.25, 0.0), at(-0.15, 0.12), at(-0.15, -0.12), at(0.25, 0.0)];
        chart.draw_series(std::iter::once(PathElement::new(tri, BASE.mix(0.6).stroke_width(1))))?;
        let arm: Vec<(f64, f64)> = arm_points(r, chain).iter().map(|p| (p[0], p[1])).collect();
        chart.draw_series(std::iter::once(PathElement::new(arm, ARM.stroke_width(1))))?;
    }
    let paths: [(&str, RGBColor, u32, View<N>); 3] = [
        ("platform", BASE, 2, |r| (r.plant.base.x, r.plant.base.y)),
        ("end effector", EFFECTOR, 1, |r| {
            (r.plant.end_effector.translation[0], r.plant.end_effector.translation[1])
        }),
        ("target", TARGET, 1, |r| (r.plant.target.translation[0], r.plant.target.translation[1])),
    ];
    for (label, colour, width, f) in paths {
        chart
            .draw_series(LineSeries::new(rows.iter().map(f), colour.stroke_width(width)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(width)));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}

fn side_view<const N: usize>(
    file: &Path,
    name: &str,
    rows: &[Row<Spatial, N>],
    chain: &Chain<f64, N>,
) -> Plot {
    let root: Area<'_> = SVGBackend::new(file, (W, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let pts: Vec<[f64; 3]> = rows
        .iter()
        .flat_map(|r| arm_points(r, chain))
        .chain(rows.iter().map(|r| {
            let t = &r.plant.target.translation;
            [t[0], t[1], t[2]]
        }))
        .collect();
    let (x0, x1) = bounds(pts.iter().map(|p| p[0]));
    let (z0, z1) = bounds(pts.iter().map(|p| p[2]).chain([0.0]));
    // Equal scales: the plot is W × H pixels.
    let aspect = f64::from(H - 60) / f64::from(W - 70);
    let span = (x1 - x0).max((z1 - z0) / aspect);
    let cx = (x0 + x1) / 2.0;
    let z_top = z0 + span * aspect;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{name}: side view"), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(cx - span / 2.0..cx + span / 2.0, z0..z_top.max(z1))?;
    chart.configure_mesh().x_desc("x (m)").y_desc("z (m)").draw()?;
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(cx - span / 2.0, 0.0), (cx + span / 2.0, 0.0)],
        BASE.stroke_width(1),
    )))?;
    for r in instants(rows) {
        let arm: Vec<(f64, f64)> = arm_points(r, chain).iter().map(|p| (p[0], p[2])).collect();
        chart.draw_series(std::iter::once(PathElement::new(arm, ARM.stroke_width(1))))?;
    }
    let paths: [(&str, RGBColor, View<N>); 2] = [
        ("end effector", EFFECTOR, |r| {
            (r.plant.end_effector.translation[0], r.plant.end_effector.translation[2])
        }),
        ("target", TARGET, |r| (r.plant.target.translation[0], r.plant.target.translation[2])),
    ];
    for (label, colour, f) in paths {
        chart
            .draw_series(LineSeries::new(rows.iter().map(f), colour.stroke_width(1)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}

/// Every platform velocity the run commanded (those that stayed zero left out).
fn velocities<const N: usize>(file: &Path, name: &str, rows: &[Row<Spatial, N>]) -> Plot {
    let all: [VelocitySeries; 4] = [
        ("v (m/s)", EFFECTOR, |c| c.v),
        ("ω (rad/s)", SECOND, |c| c.omega),
        ("v_lat (m/s)", ARM, |c| c.v_lat),
        ("v_ξ (1/(m·s))", TARGET, |c| c.v_xi),
    ];
    let used: Vec<VelocitySeries> =
        all.into_iter().filter(|s| rows.iter().any(|r| s.2(&r.report.command.platform) != 0.0)).collect();
    velocity_plot(file, name, rows, &used)
}

fn joints<const N: usize>(file: &Path, name: &str, rows: &[Row<Spatial, N>], chain: &Chain<f64, N>) -> Plot {
    let n = N;
    let height = 60 + 110 * n as u32;
    let root: Area<'_> = SVGBackend::new(file, (W, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(30);
    title.titled(&format!("{name}: joints and their limits"), ("sans-serif", 18))?;
    let t1 = rows.last().map_or(1.0, |r| r.plant.t).max(1e-3);
    for (i, area) in body.split_evenly((n, 1)).iter().enumerate() {
        let (lo, hi) = (chain.joints[i].lower, chain.joints[i].upper);
        // Joints with wide limits (±2π) are drawn over their motion, with the limits if near.
        let (m0, m1) = bounds(rows.iter().map(|r| r.plant.joints[i]));
        let (y0, y1) = (m0.max(lo - 0.05 * (hi - lo)), m1.min(hi + 0.05 * (hi - lo)));
        let (y0, y1) = if hi - lo < 4.0 { (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)) } else { (y0, y1) };
        let mut chart = ChartBuilder::on(area)
            .margin(6)
            .x_label_area_size(if i + 1 == n { 30 } else { 12 })
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..t1, y0..y1)?;
        chart.configure_mesh().y_desc(format!("q{}", i + 1)).max_light_lines(2).draw()?;
        for l in [lo, hi] {
            if (y0..=y1).contains(&l) {
                chart.draw_series(LineSeries::new(vec![(0.0, l), (t1, l)], TARGET.stroke_width(1)))?;
            }
        }
        chart.draw_series(LineSeries::new(rows.iter().map(|r| (r.plant.t, r.plant.joints[i])), EFFECTOR))?;
    }
    root.present()?;
    Ok(())
}
