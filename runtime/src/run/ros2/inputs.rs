//! The node's inputs and the HIL's safety rules over them: the latest sample of each input,
//! and whether the law may step on them now ([`Latest::check`]) or the robot gets the zero
//! command, and why ([`Fault`]).
//!
//! An input is refused, in this order, when
//!
//! 1. it never arrived (before the run starts: the node waits for it),
//! 2. it arrived malformed: a joint state without one of the arm's joints, with one listed
//!    twice, or with fewer positions than names (the whole message; extra names are ignored),
//!    a pose whose quaternion is not a unit one (within 10⁻³), or a sample that does not
//!    decode,
//! 3. it holds a value that is not finite (a position, a pose, a quaternion, a twist),
//! 4. its publisher is silent: nothing arrived for `silence` on this node's clock,
//! 5. it is stale: its header's stamp is older than `max_age` (or more than `max_age` in the
//!    future) on the system clock, which is ROS 2's time.
//!
//! A refused input is not replaced by an older good one: the robot gets the zero command
//! until a good sample arrives. Each refusal is counted by input and cause ([`FaultCounts`]).
//! Nothing here allocates.

use serde::Serialize;

use crate::domain::arm::MAX_JOINTS;
use crate::transport::ros2::msgs::{JointSample, Pose, Time, Twist};
use crate::transport::ros2::{Arrived, Inputs, StampedPose, StampedTwist};

/// The node's inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Input {
    /// `sensor_msgs/JointState`.
    JointStates,
    /// The platform's pose.
    BasePose,
    /// The target's pose.
    TargetPose,
    /// The target's twist.
    TargetTwist,
}

impl Input {
    /// Every input, in the order the checks visit them.
    pub const ALL: [Self; 4] = [Self::JointStates, Self::BasePose, Self::TargetPose, Self::TargetTwist];

    /// `joint_states`, `base_pose`, `target_pose`, `target_twist`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::JointStates => "joint_states",
            Self::BasePose => "base_pose",
            Self::TargetPose => "target_pose",
            Self::TargetTwist => "target_twist",
        }
    }
}

/// Why the robot gets the zero command this period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// The input never arrived.
    Missing(Input),
    /// Its last sample is malformed (joint names, counts, or undecodable).
    Malformed(Input),
    /// Its last sample holds a value that is not finite.
    NonFinite(Input),
    /// Nothing arrived on it for `silence`.
    Silent(Input),
    /// Its last sample's stamp is more than `max_age` from now.
    Stale(Input),
}

/// How long a sample stays good.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ages {
    /// The largest age of a sample's stamp on the system clock (ns).
    pub max_age_ns: u64,
    /// The longest silence of a publisher on the node's clock (ns).
    pub silence_ns: u64,
}

/// One input's last sample: its value (`None`: it was refused), and when it arrived on the
/// node's monotonic clock.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Slot<T> {
    value: Option<Result<T, Fault>>,
    arrived_ns: u64,
}

impl<T> Default for Slot<T> {
    fn default() -> Self {
        Self { value: None, arrived_ns: 0 }
    }
}

/// The latest of each input.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Latest {
    joints: Slot<JointSample>,
    base: Slot<StampedPose>,
    target_pose: Slot<StampedPose>,
    target_twist: Slot<StampedTwist>,
    /// The arm's joint count (the bits of a joint sample that must be set).
    joints_needed: usize,
    /// Whether the target comes from topics.
    target_read: bool,
}

/// The inputs of one step, all good.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapshot {
    /// The arm's joints, in its order (the first `N` used).
    pub joints: [f64; MAX_JOINTS],
    /// The joints' stamp.
    pub joints_stamp: Time,
    /// The platform's pose.
    pub base: Pose,
    /// Its stamp.
    pub base_stamp: Time,
    /// The target's pose and twist with their stamps, when read from topics.
    pub target: Option<(StampedPose, StampedTwist)>,
}

fn pose_finite(p: &Pose) -> bool {
    let (a, b) = (&p.position, &p.orientation);
    [a.x, a.y, a.z, b.x, b.y, b.z, b.w].iter().all(|x| x.is_finite())
}

fn twist_finite(t: &Twist) -> bool {
    let (a, b) = (&t.linear, &t.angular);
    [a.x, a.y, a.z, b.x, b.y, b.z].iter().all(|x| x.is_finite())
}

impl Latest {
    /// No input yet, for an arm of `joints` joints; `target_read`: the target comes from
    /// topics (else the node generates it).
    pub fn new(joints: usize, target_read: bool) -> Self {
        Self { joints_needed: joints.min(MAX_JOINTS), target_read, ..Self::default() }
    }

    /// Takes what arrived (at `now_ns` on the node's clock) as the latest of each input,
    /// refusing malformed and non-finite samples; counts samples that did not decode.
    pub fn update(&mut self, inputs: &Inputs, now_ns: u64, counts: &mut FaultCounts) {
        let need = self.joints_needed;
        let all = if need >= 16 { u16::MAX } else { (1u16 << need) - 1 };
        take(&mut self.joints, &inputs.joints, now_ns, Input::JointStates, counts, |s| {
            if s.malformed || s.found & all != all {
                Err(Fault::Malformed(Input::JointStates))
            } else if !s.joints[..need].iter().all(|x| x.is_finite()) {
                Err(Fault::NonFinite(Input::JointStates))
            } else {
                Ok(())
            }
        });
        let pose_check = |input| {
            move |p: &StampedPose| {
                if !pose_finite(&p.pose) {
                    Err(Fault::NonFinite(input))
                } else if super::target::rotation(&p.pose.orientation).is_none() {
                    Err(Fault::Malformed(input))
                } else {
                    Ok(())
                }
            }
        };
        take(&mut self.base, &inputs.base, now_ns, Input::BasePose, counts, pose_check(Input::BasePose));
        take(
            &mut self.target_pose,
            &inputs.target_pose,
            now_ns,
            Input::TargetPose,
            counts,
            pose_check(Input::TargetPose),
        );
        take(&mut self.target_twist, &inputs.target_twist, now_ns, Input::TargetTwist, counts, |t| {
            if twist_finite(&t.twist) {
                Ok(())
            } else {
                Err(Fault::NonFinite(Input::TargetTwist))
            }
        });
    }

    /// The inputs of a step at `now_mono_ns` (the node's clock) and `now_real_ns` (the system
    /// clock, ROS 2's time), or the first fault (module docs' order, inputs in
    /// [`Input::ALL`]'s).
    ///
    /// # Errors
    /// The [`Fault`] that gives the robot the zero command.
    pub fn check(&self, now_mono_ns: u64, now_real_ns: i64, ages: Ages) -> Result<Snapshot, Fault> {
        // Missing, then malformed or non-finite, over every input before silence and age.
        let joints = value(&self.joints, Input::JointStates)?;
        let base = value(&self.base, Input::BasePose)?;
        let target = if self.target_read {
            Some((
                value(&self.target_pose, Input::TargetPose)?,
                value(&self.target_twist, Input::TargetTwist)?,
            ))
        } else {
            None
        };
        let silent = |arrived: u64| now_mono_ns.saturating_sub(arrived) > ages.silence_ns;
        let stale = |stamp: Time| (now_real_ns - stamp.as_ns()).unsigned_abs() > ages.max_age_ns;
        let mut visits = [
            (Input::JointStates, self.joints.arrived_ns, joints.stamp),
            (Input::BasePose, self.base.arrived_ns, base.stamp),
            (Input::TargetPose, self.target_pose.arrived_ns, Time::default()),
            (Input::TargetTwist, self.target_twist.arrived_ns, Time::default()),
        ];
        if let Some((p, t)) = &target {
            visits[2].2 = p.stamp;
            visits[3].2 = t.stamp;
        }
        let n = if target.is_some() { 4 } else { 2 };
        for &(input, arrived, _) in &visits[..n] {
            if silent(arrived) {
                return Err(Fault::Silent(input));
            }
        }
        for &(input, _, stamp) in &visits[..n] {
            if stale(stamp) {
                return Err(Fault::Stale(input));
            }
        }
        Ok(Snapshot {
            joints: joints.joints,
            joints_stamp: joints.stamp,
            base: base.pose,
            base_stamp: base.stamp,
            target,
        })
    }
}

fn value<T: Copy>(slot: &Slot<T>, input: Input) -> Result<T, Fault> {
    match slot.value {
        None => Err(Fault::Missing(input)),
        Some(v) => v,
    }
}

/// The last sample of `arrived` into `slot`, checked by `ok` (a refused one is counted).
fn take<T: Copy>(
    slot: &mut Slot<T>,
    arrived: &Arrived<T>,
    now_ns: u64,
    input: Input,
    counts: &mut FaultCounts,
    ok: impl Fn(&T) -> Result<(), Fault>,
) {
    if arrived.undecodable > 0 {
        counts.undecodable[input as usize] += arrived.undecodable;
    }
    if let Some(v) = arrived.last {
        slot.arrived_ns = now_ns;
        slot.value = Some(ok(&v).map(|()| v));
    } else if arrived.undecodable > 0 {
        // The newest sample could not be read: what the robot sent last is unknown.
        slot.arrived_ns = now_ns;
        slot.value = Some(Err(Fault::Malformed(input)));
    }
}

/// Periods answered with the zero command, by cause and input (`joint_states`,
/// `base_pose`, `target_pose`, `target_twist`), and undecodable samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FaultCounts {
    /// An input never arrived (after the run started: it cannot; kept for completeness).
    pub missing: [u64; 4],
    /// A malformed sample (joint names or counts, undecodable).
    pub malformed: [u64; 4],
    /// A value not finite.
    pub non_finite: [u64; 4],
    /// A silent publisher.
    pub silent: [u64; 4],
    /// A stale stamp.
    pub stale: [u64; 4],
    /// Samples that did not decode (each counted, whether or not a period was answered
    /// with zero for it).
    pub undecodable: [u64; 4],
}

impl FaultCounts {
    /// Counts one period answered with zero for `f`.
    pub fn count(&mut self, f: Fault) {
        let (list, input) = match f {
            Fault::Missing(i) => (&mut self.missing, i),
            Fault::Malformed(i) => (&mut self.malformed, i),
            Fault::NonFinite(i) => (&mut self.non_finite, i),
            Fault::Silent(i) => (&mut self.silent, i),
            Fault::Stale(i) => (&mut self.stale, i),
        };
        list[input as usize] += 1;
    }

    /// Periods answered with zero for any input fault.
    pub fn total(&self) -> u64 {
        [&self.missing, &self.malformed, &self.non_finite, &self.silent, &self.stale]
            .iter()
            .map(|l| l.iter().sum::<u64>())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::ros2::msgs::{Quaternion, Vector3};

    const AGES: Ages = Ages { max_age_ns: 5_000_000, silence_ns: 20_000_000 };

    fn joints(stamp_ns: i64, names_found: u16, q: [f64; 2]) -> JointSample {
        let mut joints = [f64::NAN; MAX_JOINTS];
        joints[..2].copy_from_slice(&q);
        JointSample { stamp: Time::from_ns(stamp_ns), joints, found: names_found, malformed: false }
    }

    fn pose(stamp_ns: i64, x: f64) -> StampedPose {
        StampedPose {
            stamp: Time::from_ns(stamp_ns),
            pose: Pose { position: Vector3 { x, y: 0.0, z: 0.0 }, orientation: Quaternion::default() },
        }
    }

    fn arrived<T>(v: T) -> Arrived<T> {
        Arrived { last: Some(v), samples: 1, undecodable: 0 }
    }

    fn inputs(j: JointSample, b: StampedPose) -> Inputs {
        Inputs { joints: arrived(j), base: arrived(b), ..Inputs::default() }
    }

    #[test]
    fn good_fresh_inputs_make_a_snapshot() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Missing(Input::JointStates)));
        l.update(&inputs(joints(1_000_000, 0b11, [0.1, 0.2]), pose(1_000_000, 3.0)), 100, &mut c);
        let s = l.check(200, 2_000_000, AGES).unwrap();
        assert_eq!(&s.joints[..2], &[0.1, 0.2]);
        assert_eq!(s.base.position.x, 3.0);
        assert_eq!(s.joints_stamp.as_ns(), 1_000_000);
        assert_eq!(c, FaultCounts::default());
    }

    #[test]
    fn a_missing_joint_name_and_a_non_finite_value_are_refused_until_a_good_sample() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        l.update(&inputs(joints(0, 0b01, [0.1, f64::NAN]), pose(0, 1.0)), 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Malformed(Input::JointStates)));
        // A good sample, then a non-finite one: the good one is not used again.
        l.update(&inputs(joints(0, 0b11, [0.1, 0.2]), pose(0, 1.0)), 0, &mut c);
        assert!(l.check(0, 0, AGES).is_ok());
        let j = Inputs { joints: arrived(joints(0, 0b11, [0.1, f64::INFINITY])), ..Inputs::default() };
        l.update(&j, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::NonFinite(Input::JointStates)));
        let b = Inputs {
            joints: arrived(joints(0, 0b11, [0.1, 0.2])),
            base: arrived(pose(0, f64::NAN)),
            ..Inputs::default()
        };
        l.update(&b, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::NonFinite(Input::BasePose)));
        // A name listed twice.
        let mut dup = joints(0, 0b11, [0.1, 0.2]);
        dup.malformed = true;
        l.update(&inputs(dup, pose(0, 1.0)), 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Malformed(Input::JointStates)));
        // An undecodable newest sample.
        let u = Inputs { joints: Arrived { last: None, samples: 0, undecodable: 2 }, ..Inputs::default() };
        l.update(&u, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Malformed(Input::JointStates)));
        assert_eq!(c.undecodable, [2, 0, 0, 0]);
    }

    #[test]
    fn silence_and_age_are_refused_at_their_limits() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        l.update(&inputs(joints(10_000_000, 0b11, [0.1, 0.2]), pose(10_000_000, 1.0)), 1_000, &mut c);
        // Age: exactly max_age is good, one ns more is stale; a stamp from the future too.
        assert!(l.check(1_000, 15_000_000, AGES).is_ok());
        assert_eq!(l.check(1_000, 15_000_001, AGES), Err(Fault::Stale(Input::JointStates)));
        assert_eq!(l.check(1_000, 4_999_999, AGES), Err(Fault::Stale(Input::JointStates)));
        // Silence: on the node's clock, whatever the stamps say.
        assert!(l.check(20_001_000, 10_000_000, AGES).is_ok());
        assert_eq!(l.check(20_001_001, 10_000_000, AGES), Err(Fault::Silent(Input::JointStates)));
        // Only the base stale.
        let b = Inputs { base: arrived(pose(0, 1.0)), ..Inputs::default() };
        l.update(&b, 1_000, &mut c);
        assert_eq!(l.check(1_000, 10_000_000, AGES), Err(Fault::Stale(Input::BasePose)));
    }

    #[test]
    fn the_target_read_from_topics_is_checked_as_the_robot_is() {
        let mut l = Latest::new(2, true);
        let mut c = FaultCounts::default();
        l.update(&inputs(joints(0, 0b11, [0.1, 0.2]), pose(0, 1.0)), 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Missing(Input::TargetPose)));
        let twist = StampedTwist { stamp: Time::from_ns(0), twist: Twist::default() };
        let t =
            Inputs { target_pose: arrived(pose(0, 2.0)), target_twist: arrived(twist), ..Inputs::default() };
        l.update(&t, 0, &mut c);
        let s = l.check(0, 0, AGES).unwrap();
        assert_eq!(s.target.map(|(p, _)| p.pose.position.x), Some(2.0));
        let mut bad = twist;
        bad.twist.angular.z = f64::NAN;
        l.update(&Inputs { target_twist: arrived(bad), ..Inputs::default() }, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::NonFinite(Input::TargetTwist)));
    }

    #[test]
    fn faults_are_counted_by_cause_and_input() {
        let mut c = FaultCounts::default();
        for f in
            [Fault::Stale(Input::BasePose), Fault::Stale(Input::BasePose), Fault::Silent(Input::TargetTwist)]
        {
            c.count(f);
        }
        assert_eq!(c.stale, [0, 2, 0, 0]);
        assert_eq!(c.silent, [0, 0, 0, 1]);
        assert_eq!(c.total(), 3);
    }
}
