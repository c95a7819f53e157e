//! Where and why the default law leaves the continuous one: the time series behind the
//! precision chapter's "On the continuous law's path" table, for one run (unicycle, the paper's
//! parameters):
//!
//! ```text
//! cargo run --release -p companion-tests --example pointwise_where -- FROM TO EVERY [t1a|t2a|t1c]
//! cargo run --release -p companion-tests --example pointwise_where -- 7.3 7.7 0.01 t2a
//! ```
//!
//! On stderr the largest difference at 1, 0.5 and 0.25 ms (the 1 ms instants, as the
//! table). On stdout, every `EVERY` seconds of `[FROM, TO]`: the default law at 1 ms minus
//! the continuous closed loop ([`reference`], RK4 at 1e-5 s) for `x_b, y_b, θ_b, q₁..q₃`;
//! `q₁`'s difference at 1 ms, 4× at 0.5 ms, 16× at 0.25 ms (equal where the difference is
//! second order); the difference of the transverse function's `α` (`Δα`, rad) and the part
//! of `q₁`'s difference it explains, `Δα q̇₁/α̇` (the state displaced along the loop's
//! motion by the phase of `α`), with the residual; and the law's diagnostics at 1 ms that a
//! sampling error could come from: `α`, `α̇`, `ū_b`, `det H`, the joint penalty `h_ℓ`, the
//! condition number of `∂e_m/∂q`, the platform step's weight `a`, the saturation `1/ρ`, the
//! joint guard's factor, the command `(v, ω, u_q)` and `‖e_p‖`.

use companion_core::{wrap_angle, Controller, PaperRun, PlatformKind, Rpr, Unicycle};
use companion_plant::{paper_initial, PaperTrajectory, Plant, PlantConfig, Trajectory};
use companion_runtime::domain::controller::{ControllerSpec, Scalar};
use companion_tests::pointwise::{reference, reference_alpha, worst, Sample};

/// One step of the default law: the plant's state at `t_k` and what the law reported.
struct Row {
    s: Sample,
    alpha: f64,
    alpha_rate: f64,
    diag: [f64; 15],
}

fn run(tr: PaperTrajectory, r: PaperRun, period: f64, duration: f64) -> Vec<Row> {
    let spec = ControllerSpec::paper(PlatformKind::Unicycle, r, Scalar::F64);
    let mut c: Controller<f64, Unicycle<f64>, Rpr<f64>, 3> =
        Controller::new(spec.params::<f64>(), spec.unicycle(), spec.arm()).expect("paper parameters");
    let mut plant = Plant::new(
        PlantConfig::new(PlatformKind::Unicycle),
        Rpr::paper(),
        paper_initial(tr),
        Trajectory::from(tr),
    )
    .expect("paper plant");
    let mut out = Vec::new();
    for _ in 0..=(duration / period).round() as usize {
        let t = plant.truth();
        let s = [t.base.x, t.base.y, t.base.theta, t.joints[0], t.joints[1], t.joints[2]];
        let o = c.step(&plant.measure(), period).expect("the default law accepts the paper's runs");
        let (g, u) = (&o.diagnostics, &o.command);
        out.push(Row {
            s,
            alpha: g.alpha[0],
            alpha_rate: g.alpha_rate[0],
            diag: [
                g.u_bar[0],
                g.u_bar[1],
                g.u_bar[2],
                g.det_h,
                g.joint_penalty,
                g.condition,
                g.implicitness,
                g.saturation,
                g.joint_scale,
                u.platform.v,
                u.platform.omega,
                u.joints[0],
                u.joints[1],
                u.joints[2],
                g.e_p.norm(),
            ],
        });
        plant.advance(&o.command, period);
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: f64| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let (from, to, every) = (arg(1, 7.3), arg(2, 7.7), arg(3, 0.01));
    let name = args.get(4).map_or("t2a", String::as_str);
    let (tr, r) = match name {
        "t1a" => (PaperTrajectory::One, PaperRun::A),
        "t1c" => (PaperTrajectory::One, PaperRun::C),
        _ => (PaperTrajectory::Two, PaperRun::A),
    };
    let duration = 10.0;
    let fine = reference(tr, r, 1e-5, duration, 100);
    let fine_alpha = reference_alpha(tr, r, 1e-5, duration, 100);
    let runs = [run(tr, r, 1e-3, duration), run(tr, r, 5e-4, duration), run(tr, r, 2.5e-4, duration)];
    for (k, rows) in runs.iter().enumerate() {
        let stride = 1 << k;
        let at_1ms: Vec<Sample> = rows.iter().step_by(stride).map(|r| r.s).collect();
        let (d, at, comp) = worst(&at_1ms, &fine);
        eprintln!(
            "{name} at {} ms: {d:.3e} at t = {:.3} s, component {comp}",
            1.0 / stride as f64,
            at as f64 * 1e-3
        );
    }
    println!(
        "t | Δ(1 ms) x_b y_b θ_b q1 q2 q3 | Δq1: 1 ms, 4×0.5 ms, 16×0.25 ms | Δα, Δα·q̇1/α̇, residual | \
         α α̇ ū_b(3) det_H h_l cond a 1/ρ guard v ω u_q(3) ‖e_p‖"
    );
    let mut i = (from / 1e-3).round() as usize;
    while i < fine.len() && i as f64 * 1e-3 <= to + 1e-9 {
        let (f, a) = (&fine[i], &runs[0][i]);
        let d: Vec<String> = (0..6).map(|c| format!("{:+.2e}", a.s[c] - f[c])).collect();
        let dq1 = a.s[3] - f[3];
        let d_alpha = wrap_angle(a.alpha - fine_alpha[i]);
        let along = if a.alpha_rate != 0.0 { d_alpha * a.diag[11] / a.alpha_rate } else { 0.0 };
        let g: Vec<String> = a.diag.iter().map(|v| format!("{v:+.3e}")).collect();
        println!(
            "{:.3} | {} | {dq1:+.3e} {:+.3e} {:+.3e} | {d_alpha:+.3e} {along:+.3e} {:+.2e} | {:+.4} {:+.3e} {}",
            i as f64 * 1e-3,
            d.join(" "),
            4.0 * (runs[1][2 * i].s[3] - f[3]),
            16.0 * (runs[2][4 * i].s[3] - f[3]),
            dq1 - along,
            a.alpha,
            a.alpha_rate,
            g.join(" ")
        );
        i += ((every / 1e-3).round() as usize).max(1);
    }
}
