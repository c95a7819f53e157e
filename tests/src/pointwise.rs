//! The continuous closed loop of the paper's runs, integrated finely, as a reference for the
//! sampled-data law's pointwise distance from it.
//!
//! The continuous law is the core's own law evaluated at the current state with nothing of
//! the hold in it: `Discretisation::Sampled` with the explicit rest filter (the command is
//! then (37), (14) and (30) at the state, and the controller's filters `α`, `q̂`, `Ψ`, `σ`,
//! `r̃_b` advance by their rates times the period — so a step of length `H` from a state
//! gives those rates as `(z' − z)/H`). The closed loop — unicycle `ṙ_b = R̄(θ_b) (v, 0, ω)`,
//! joints `q̇ = u_q`, target `ṙ_d = R̄(θ_d) u_d(t)` and the controller's filters — is
//! integrated by classical RK4 at a fixed step with the law evaluated at every stage (no
//! hold anywhere). The sampled-data runs it is compared with are the plant
//! ([`companion_plant::Plant`]) under the held commands of the default law.

use companion_core::nalgebra::{SVector, Vector2, Vector3};
use companion_core::{
    Controller, Discretisation, Measurement, PaperRun, PlatformKind, Pose, RestFilter, Rpr, State, Unicycle,
};
use companion_plant::{paper_initial, PaperTrajectory, Plant, PlantConfig, Trajectory};
use companion_runtime::domain::controller::{ControllerSpec, Scalar};

/// The six state components compared: `x_b`, `y_b`, `θ_b`, `q₁`, `q₂`, `q₃`.
pub type Sample = [f64; 6];

/// The closed loop's state: plant (base, joints, target) and the controller's filters.
#[derive(Clone, Copy, Debug)]
struct Loop {
    base: Vector3<f64>,
    q: SVector<f64, 3>,
    target: Vector3<f64>,
    alpha: Vector2<f64>,
    q_hat: SVector<f64, 3>,
    psi: f64,
    sigma: SVector<f64, 3>,
    r_tilde: Vector3<f64>,
}

impl Loop {
    fn axpy(&self, k: f64, d: &Loop) -> Loop {
        Loop {
            base: self.base + d.base * k,
            q: self.q + d.q * k,
            target: self.target + d.target * k,
            alpha: self.alpha + d.alpha * k,
            q_hat: self.q_hat + d.q_hat * k,
            psi: self.psi + d.psi * k,
            sigma: self.sigma + d.sigma * k,
            r_tilde: self.r_tilde + d.r_tilde * k,
        }
    }

    fn sample(&self) -> Sample {
        [self.base[0], self.base[1], self.base[2], self.q[0], self.q[1], self.q[2]]
    }
}

fn pose_rate(theta: f64, u: &Vector3<f64>) -> Vector3<f64> {
    let (s, c) = theta.sin_cos();
    Vector3::new(c * u[0] - s * u[1], s * u[0] + c * u[1], u[2])
}

/// `a − b` for angles, in `(−π, π]`.
fn angle_diff(a: f64, b: f64) -> f64 {
    companion_core::wrap_angle(a - b)
}

type Uni = Controller<f64, Unicycle<f64>, Rpr<f64>, 3>;

/// The paper's unicycle controller for `run`, with `discretisation`.
/// The paper's law for `run` (unicycle) with the default parameters but `discretisation`.
fn controller_with(run: PaperRun, discretisation: Discretisation) -> Uni {
    let spec = ControllerSpec::paper(PlatformKind::Unicycle, run, Scalar::F64);
    let mut params = spec.params::<f64>();
    params.discretisation = discretisation;
    Controller::new(params, spec.unicycle(), spec.arm()).expect("the paper's parameters are valid")
}

fn controller(run: PaperRun, continuous: bool) -> Uni {
    let spec = ControllerSpec::paper(PlatformKind::Unicycle, run, Scalar::F64);
    let mut params = spec.params::<f64>();
    if continuous {
        params.discretisation = Discretisation::Sampled;
        params.secondary.rest_filter = RestFilter::Explicit;
    }
    Controller::new(params, spec.unicycle(), spec.arm()).expect("the paper's parameters are valid")
}

/// The continuous law and the closed loop's right-hand side.
struct Continuous {
    law: Uni,
    trajectory: Trajectory,
    /// The state the law is evaluated from (initialised; its filters overwritten each time).
    template: State<f64, 3>,
}

/// The period a rate is read over (the law is affine in it for these runs).
const PROBE: f64 = 1e-5;

impl Continuous {
    fn state_of(&self, x: &Loop) -> State<f64, 3> {
        let mut s = self.template;
        s.alpha = x.alpha;
        s.q_hat = x.q_hat;
        s.psi = x.psi;
        s.sigma = x.sigma;
        s.r_tilde = Pose::new(x.r_tilde[0], x.r_tilde[1], x.r_tilde[2]);
        s
    }

    /// `ẋ` at `t`, with the target's velocity `u_d` taken at `t_u` (the same piece of
    /// trajectory 2's table for every stage of one step).
    fn rate(&self, t: f64, t_u: f64, x: &Loop) -> Loop {
        let u_d = self.trajectory.velocity(t_u);
        let meas = Measurement {
            t,
            base: Pose::new(x.base[0], x.base[1], x.base[2]),
            steering: 0.0,
            joints: x.q,
            target: Pose::new(x.target[0], x.target[1], x.target[2]),
            target_velocity: u_d,
        };
        let before = self.state_of(x);
        let mut after = before;
        let out = self.law.law.step(&mut after, &meas, PROBE).expect("the continuous law accepts the state");
        let c = &out.command;
        let inv = 1.0 / PROBE;
        Loop {
            base: pose_rate(x.base[2], &Vector3::new(c.platform.v, 0.0, c.platform.omega)),
            q: c.joints,
            target: pose_rate(x.target[2], &u_d),
            alpha: Vector2::new(
                angle_diff(after.alpha[0], before.alpha[0]) * inv,
                angle_diff(after.alpha[1], before.alpha[1]) * inv,
            ),
            q_hat: (after.q_hat - before.q_hat) * inv,
            psi: (after.psi - before.psi) * inv,
            sigma: (after.sigma - before.sigma) * inv,
            r_tilde: Vector3::new(
                (after.r_tilde.x - before.r_tilde.x) * inv,
                (after.r_tilde.y - before.r_tilde.y) * inv,
                angle_diff(after.r_tilde.theta, before.r_tilde.theta) * inv,
            ),
        }
    }
}

/// The continuous closed loop of `trajectory`, run `run` (unicycle, the paper's parameters)
/// integrated by RK4 at `step` seconds for `duration` seconds; the six components every
/// `every` steps (the first at `t = 0`).
///
/// # Panics
/// If the continuous law rejects a state (it does not on the paper's runs).
pub fn reference(
    trajectory: PaperTrajectory,
    run: PaperRun,
    step: f64,
    duration: f64,
    every: usize,
) -> Vec<Sample> {
    integrate(trajectory, run, step, duration, every, Loop::sample)
}

/// [`reference()`]'s transverse-function parameter `α` (the unicycle's one component, rad) at
/// the same instants.
///
/// # Panics
/// If the continuous law rejects a state (it does not on the paper's runs).
pub fn reference_alpha(
    trajectory: PaperTrajectory,
    run: PaperRun,
    step: f64,
    duration: f64,
    every: usize,
) -> Vec<f64> {
    integrate(trajectory, run, step, duration, every, |x| x.alpha[0])
}

fn integrate<R>(
    trajectory: PaperTrajectory,
    run: PaperRun,
    step: f64,
    duration: f64,
    every: usize,
    sample: impl Fn(&Loop) -> R,
) -> Vec<R> {
    let init = paper_initial(trajectory);
    let law = controller(run, true);
    let trajectory = Trajectory::from(trajectory);
    // The filters' initial values (SPEC §3): those of the law's first step, read from a step
    // of a vanishing period (its rates times 1e-300 leave them as they were).
    let mut template = law.state;
    let meas0 = Measurement {
        t: 0.0,
        base: init.base,
        steering: 0.0,
        joints: init.joints,
        target: init.target,
        target_velocity: trajectory.velocity(0.0),
    };
    law.law.step(&mut template, &meas0, 1e-300).expect("the first step");
    let mut x = Loop {
        base: init.base.to_vector(),
        q: init.joints,
        target: init.target.to_vector(),
        alpha: template.alpha,
        q_hat: template.q_hat,
        psi: template.psi,
        sigma: template.sigma,
        r_tilde: Vector3::new(template.r_tilde.x, template.r_tilde.y, template.r_tilde.theta),
    };
    let f = Continuous { law, trajectory, template };
    let steps = (duration / step).round() as usize;
    let mut out = Vec::with_capacity(steps / every + 1);
    out.push(sample(&x));
    for n in 0..steps {
        let (t0, t1) = (n as f64 * step, (n + 1) as f64 * step);
        let tm = 0.5 * (t0 + t1);
        // One piece of u_d per step, the one at its midpoint (trajectory 2's jumps fall on
        // the steps' edges).
        let k1 = f.rate(t0, tm - 0.5 * step * (1.0 - 1e-6), &x);
        let k2 = f.rate(tm, tm, &x.axpy(0.5 * step, &k1));
        let k3 = f.rate(tm, tm, &x.axpy(0.5 * step, &k2));
        let k4 = f.rate(t1, tm + 0.5 * step * (1.0 - 1e-6), &x.axpy(step, &k3));
        let sum = k1.axpy(2.0, &k2).axpy(2.0, &k3).axpy(1.0, &k4);
        x = x.axpy(step / 6.0, &sum);
        if (n + 1) % every == 0 {
            out.push(sample(&x));
        }
    }
    out
}

/// The plant under the default (hold-aware) law at `period` for `duration` seconds: the six
/// components at every step (the first at `t = 0`).
///
/// # Panics
/// If the law rejects a measurement (it does not on the paper's runs).
pub fn sampled(trajectory: PaperTrajectory, run: PaperRun, period: f64, duration: f64) -> Vec<Sample> {
    sampled_motion(trajectory, run, period, duration).0
}

/// [`sampled`] under the literal sampling of the paper's law ([`Discretisation::Sampled`]:
/// evaluated at the measured state, first order in the period) instead of the default.
///
/// # Panics
/// If the law rejects a measurement (it does not on the paper's runs).
pub fn sampled_literal(
    trajectory: PaperTrajectory,
    run: PaperRun,
    period: f64,
    duration: f64,
) -> Vec<Sample> {
    motion_under(controller_with(run, Discretisation::Sampled), trajectory, period, duration).0
}

/// What the default law did at one step: the transverse function's `α` at `t_k` (rad), the
/// held `α̇` (rad/s) and the joint command `u_q`.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    /// `α(t_k)` (rad).
    pub alpha: f64,
    /// `α̇` held over the step (rad/s).
    pub alpha_rate: f64,
    /// `u_q` held over the step.
    pub u_q: [f64; 3],
}

/// [`sampled`] with, at every step, what the law did ([`Motion`]; one fewer than the samples).
///
/// # Panics
/// If the law rejects a measurement (it does not on the paper's runs).
pub fn sampled_motion(
    trajectory: PaperTrajectory,
    run: PaperRun,
    period: f64,
    duration: f64,
) -> (Vec<Sample>, Vec<Motion>) {
    motion_under(controller(run, false), trajectory, period, duration)
}

/// The plant under `c` at `period` for `duration` seconds, with what the law did.
fn motion_under(
    mut c: Uni,
    trajectory: PaperTrajectory,
    period: f64,
    duration: f64,
) -> (Vec<Sample>, Vec<Motion>) {
    let mut plant = Plant::new(
        PlantConfig::new(PlatformKind::Unicycle),
        Rpr::paper(),
        paper_initial(trajectory),
        Trajectory::from(trajectory),
    )
    .expect("the paper's plant");
    let steps = (duration / period).round() as usize;
    let sample = |p: &Plant<Rpr<f64>, 3>| {
        let s = p.truth();
        [s.base.x, s.base.y, s.base.theta, s.joints[0], s.joints[1], s.joints[2]]
    };
    let (mut out, mut motion) = (vec![sample(&plant)], Vec::with_capacity(steps));
    for _ in 0..steps {
        let o = c.step(&plant.measure(), period).expect("the default law accepts the paper's runs");
        let (g, u) = (&o.diagnostics, &o.command.joints);
        motion.push(Motion { alpha: g.alpha[0], alpha_rate: g.alpha_rate[0], u_q: [u[0], u[1], u[2]] });
        plant.advance(&o.command, period);
        out.push(sample(&plant));
    }
    (out, motion)
}

/// The largest difference of any component between two series sampled at the same instants.
pub fn distance(a: &[Sample], b: &[Sample]) -> f64 {
    a.iter().zip(b).flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs())).fold(0.0, f64::max)
}

/// Where the largest difference is: `(difference, sample index, component)`.
pub fn worst(a: &[Sample], b: &[Sample]) -> (f64, usize, usize) {
    let mut w = (0.0, 0, 0);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        for (c, (u, v)) in x.iter().zip(y).enumerate() {
            if (u - v).abs() > w.0 {
                w = ((u - v).abs(), i, c);
            }
        }
    }
    w
}

/// `series` (sampled every `own` seconds) at the instants `k·at` (`at` a multiple of `own`).
pub fn every(series: &[Sample], own: f64, at: f64) -> Vec<Sample> {
    let stride = (at / own).round() as usize;
    series.iter().step_by(stride.max(1)).copied().collect()
}
