//! The robot's command delay, estimated by the node from its own joint states: how long after
//! the node stamped a command the robot's joints started moving by it.
//!
//! A velocity-controlled joint moves by the commands it applies: between two joint states
//! stamped `s_a < s_b`, `q(s_b) − q(s_a) = Σ_j c_j · |[t_j + L, t_{j+1} + L] ∩ [s_a, s_b]|`,
//! where `c_j` is the command stamped `t_j` (held until the next) and `L` the delay from a
//! command's stamp to its application. The node keeps its last [`CAPACITY`] commands and joint
//! states (storage allocated once, before the run) and, after the run, takes the `L` in
//! `[0, 3 periods]` (a grid of a period/200) that fits the joints' motion best (least squares over
//! every joint and pair of consecutive states). The command's stamp is taken as the period
//! starts, before the law steps, the moment the measurement's age is counted to: `L` (the node's
//! own work, the transport and the robot's cycle) is the rest of the delay the law predicts
//! over, what `--command-latency` tells it.
//!
//! It needs motion (a robot that does not move tells nothing: no estimate) and a robot whose
//! joints follow their velocity commands (a kinematic stand-in exactly; a real arm's velocity
//! loop adds its own lag, which the estimate then includes).

use serde::Serialize;

/// How many periods the estimate looks back on.
pub const CAPACITY: usize = 4096;

/// A ring of the last [`CAPACITY`] items (allocated once).
#[derive(Debug)]
struct Ring<T> {
    items: Vec<T>,
    next: usize,
}

impl<T: Copy> Ring<T> {
    fn new() -> Self {
        Self { items: Vec::with_capacity(CAPACITY), next: 0 }
    }

    /// Adds `x` (no allocation: within the capacity reserved).
    fn push(&mut self, x: T) {
        if self.items.len() < CAPACITY {
            self.items.push(x);
        } else {
            self.items[self.next] = x;
        }
        self.next = (self.next + 1) % CAPACITY;
    }

    /// Oldest first.
    fn ordered(&self) -> Vec<T> {
        if self.items.len() < CAPACITY {
            self.items.clone()
        } else {
            self.items[self.next..].iter().chain(&self.items[..self.next]).copied().collect()
        }
    }
}

/// The commands and joint states of the last periods.
#[derive(Debug)]
pub struct DelayProbe<const N: usize> {
    commands: Ring<(i64, [f64; N])>,
    joints: Ring<(i64, [f64; N])>,
    last_joint_stamp: i64,
}

/// The estimate, in `summary.json`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DelayEstimate {
    /// The delay from a command's stamp to the robot applying it (s).
    pub latency_s: f64,
    /// The residual of the fit, root mean square over joints and pairs of states (rad or m).
    pub residual_rms: f64,
    /// The joints' motion between states, root mean square (rad or m): the residual's scale.
    pub motion_rms: f64,
    /// The pairs of joint states fitted.
    pub pairs: usize,
}

impl<const N: usize> Default for DelayProbe<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> DelayProbe<N> {
    /// Storage for [`CAPACITY`] periods, allocated here.
    pub fn new() -> Self {
        Self { commands: Ring::new(), joints: Ring::new(), last_joint_stamp: i64::MIN }
    }

    /// The command stamped `stamp_ns` (the system clock), its joint velocities.
    pub fn command(&mut self, stamp_ns: i64, joints: &[f64; N]) {
        self.commands.push((stamp_ns, *joints));
    }

    /// A joint state the law stepped on (each stamp kept once).
    pub fn joints(&mut self, stamp_ns: i64, q: &[f64]) {
        if stamp_ns == self.last_joint_stamp || q.len() < N {
            return;
        }
        self.last_joint_stamp = stamp_ns;
        let mut a = [0.0; N];
        a.copy_from_slice(&q[..N]);
        self.joints.push((stamp_ns, a));
    }

    /// The delay that fits the joints' motion best, over `[0, 3 periods]` (module docs); `None`
    /// without enough motion or samples.
    pub fn estimate(&self, period_ns: u64) -> Option<DelayEstimate> {
        let cmds = self.commands.ordered();
        let joints = self.joints.ordered();
        if cmds.len() < 10 || joints.len() < 10 {
            return None;
        }
        let period = period_ns as i64;
        let step = (period / 200).max(1);
        // Pairs of consecutive joint states wholly after the first command plus the largest
        // delay tried (so that every command acting between them is known).
        let first = cmds[0].0 + 3 * period;
        let last_cmd = cmds[cmds.len() - 1].0;
        let pairs: Vec<_> =
            joints.windows(2).filter(|w| w[0].0 >= first && w[1].0 <= last_cmd && w[1].0 > w[0].0).collect();
        if pairs.len() < 10 {
            return None;
        }
        let motion: f64 =
            pairs.iter().map(|w| (0..N).map(|i| (w[1].1[i] - w[0].1[i]).powi(2)).sum::<f64>()).sum();
        let count = (pairs.len() * N) as f64;
        let motion_rms = (motion / count).sqrt();
        if motion_rms.is_nan() || motion_rms <= 1e-9 {
            return None;
        }
        let residual = |l: i64| -> f64 {
            let mut sum = 0.0;
            for w in &pairs {
                let (sa, sb) = (w[0].0, w[1].0);
                let mut predicted = [0.0; N];
                // The first command that may act in [sa, sb]: the last applied at or before sa.
                let mut j = cmds.partition_point(|c| c.0 + l <= sa).saturating_sub(1);
                while j < cmds.len() && cmds[j].0 + l < sb {
                    let from = (cmds[j].0 + l).max(sa);
                    let to = cmds.get(j + 1).map_or(sb, |c| c.0 + l).min(sb);
                    if to > from {
                        let dt = (to - from) as f64 * 1e-9;
                        for (p, c) in predicted.iter_mut().zip(&cmds[j].1) {
                            *p += c * dt;
                        }
                    }
                    j += 1;
                }
                for ((b, a), p) in w[1].1.iter().zip(&w[0].1).zip(&predicted) {
                    sum += (b - a - p).powi(2);
                }
            }
            sum
        };
        let (best, r) = (0..=3 * period / step)
            .map(|k| (k * step, residual(k * step)))
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        Some(DelayEstimate {
            latency_s: best as f64 * 1e-9,
            residual_rms: (r / count).sqrt(),
            motion_rms,
            pairs: pairs.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kinematic joint sampled every `sample_ns`, driven by commands every `period_ns` that it
    /// applies `delay_ns` after their stamps; sampled at a phase of its own.
    fn simulated(delay_ns: i64, period_ns: i64, sample_ns: i64, phase_ns: i64) -> DelayProbe<2> {
        let mut probe = DelayProbe::<2>::new();
        let cmd = |k: i64| [(k as f64 * 0.37).sin(), (k as f64 * 0.11).cos()];
        let mut q = [0.0f64; 2];
        let mut t = 0i64;
        let dt = 10_000; // 10 µs of integration
        let end = 2_000 * period_ns;
        let mut next_sample = phase_ns;
        while t < end {
            // The command in force at t: the last stamped at or before t - delay.
            let k = (t - delay_ns).div_euclid(period_ns);
            let c = if t - delay_ns >= 0 { cmd(k) } else { [0.0, 0.0] };
            if t % period_ns == 0 {
                probe.command(t, &cmd(t / period_ns));
            }
            if t >= next_sample {
                probe.joints(t, &q);
                next_sample += sample_ns;
            }
            q[0] += c[0] * dt as f64 * 1e-9;
            q[1] += c[1] * dt as f64 * 1e-9;
            t += dt;
        }
        probe
    }

    #[test]
    fn the_delay_of_a_kinematic_robot_is_found_within_the_grid() {
        for (delay, sample, phase) in
            [(700_000, 10_000_000, 3_300_000), (2_500_000, 10_000_000, 0), (0, 5_000_000, 1_230_000)]
        {
            let e = simulated(delay, 10_000_000, sample, phase).estimate(10_000_000).unwrap();
            assert!((e.latency_s - delay as f64 * 1e-9).abs() <= 60e-6, "{delay}: {e:?}");
            assert!(e.residual_rms < 1e-3 * e.motion_rms, "{e:?}");
        }
    }

    #[test]
    fn no_motion_no_estimate() {
        let mut p = DelayProbe::<2>::new();
        for k in 0..100 {
            p.command(k * 1_000_000, &[0.0, 0.0]);
            p.joints(k * 1_000_000 + 500, &[1.0, 2.0]);
        }
        assert_eq!(p.estimate(1_000_000), None);
    }
}
