//! The node's inputs and the HIL's safety rules over them: the latest sample of each input,
//! and whether the law may step on them now ([`Latest::check`]) or the robot gets the zero
//! command, and why ([`Fault`]).
//!
//! An input is refused, in this order, when
//!
//! 0. it has a second writer ([`Writers`]): another DDS writer than the input's own is on its
//!    topic (DDS discovery says so) or sent a sample within `silence`,
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
//!
//! ## One writer per input
//!
//! Each input has its own writer: the first DDS writer whose samples arrive while it is the
//! only writer of the topic. Only its samples are ever used; another writer's are refused and
//! counted, and while another writer is present — on the topic by discovery, or a sample of
//! it within `silence` — the robot gets the zero command ([`Fault::SecondWriter`]). A new
//! writer is taken only when the input's own has left (it is silent and discovery lists one
//! writer at most: a driver restarted), and the change is counted.

use serde::Serialize;

use crate::domain::arm::MAX_JOINTS;
use crate::transport::ros2::msgs::{JointSample, Pose, Time, Twist};
use crate::transport::ros2::{Arrived, Inputs, StampedPose, StampedTwist, WriterId};

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
    /// Another writer than the input's own is on its topic or sent samples.
    SecondWriter(Input),
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

/// The most other writers of one input told apart (more are counted together).
pub const MAX_OTHERS: usize = 8;

/// A writer of an input other than its own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Other {
    /// The writer.
    pub id: WriterId,
    /// Its samples, refused.
    pub samples: u64,
    /// When its first and last samples arrived (the node's clock, ns).
    pub first_ns: u64,
    /// When its last sample arrived.
    pub last_ns: u64,
}

/// An input's writers: its own, and the others seen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Writers {
    /// The input's own writer (none yet, or none since it left).
    pub own: Option<WriterId>,
    /// Its samples taken (each checked as any sample).
    pub own_samples: u64,
    /// Writers the input took in turn after its first (a driver restarted).
    pub adopted: u64,
    /// The other writers that sent samples.
    pub others: [Option<Other>; MAX_OTHERS],
    /// Samples of other writers past [`MAX_OTHERS`].
    pub others_overflow: u64,
    /// The largest number of remote writers discovery listed on the topic at once.
    pub max_listed: u32,
    /// The other writer seen last, and when (the node's clock).
    last_other: Option<(WriterId, u64)>,
}

impl Writers {
    /// Notes refused samples of `id` at `now_ns`.
    fn refuse(&mut self, id: WriterId, n: u64, now_ns: u64) {
        self.last_other = Some((id, now_ns));
        for o in &mut self.others {
            match o {
                Some(x) if x.id == id => {
                    x.samples += n;
                    x.last_ns = now_ns;
                    return;
                }
                None => {
                    *o = Some(Other { id, samples: n, first_ns: now_ns, last_ns: now_ns });
                    return;
                }
                Some(_) => {}
            }
        }
        self.others_overflow += n;
    }

    /// The other writer whose sample came last, if within `silence_ns` of `now_ns`.
    pub fn recent_other(&self, now_ns: u64, silence_ns: u64) -> Option<WriterId> {
        self.last_other.filter(|(_, t)| now_ns.saturating_sub(*t) <= silence_ns).map(|(w, _)| w)
    }

    /// Whether no writer but `id` and the input's own sent a sample within `silence_ns` of
    /// `now_ns`.
    fn quiet_but(&self, id: WriterId, now_ns: u64, silence_ns: u64) -> bool {
        let recent = |t: u64| now_ns.saturating_sub(t) <= silence_ns;
        self.others.iter().flatten().all(|o| o.id == id || !recent(o.last_ns))
            && !(self.others_overflow > 0 && self.last_other.is_some_and(|(w, t)| w != id && recent(t)))
    }

    /// Whether any writer other than the input's own sent a sample.
    pub fn had_others(&self) -> bool {
        self.others[0].is_some()
    }
}

/// The latest of each input.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Latest {
    joints: Slot<JointSample>,
    base: Slot<StampedPose>,
    target_pose: Slot<StampedPose>,
    target_twist: Slot<StampedTwist>,
    /// Each input's writers.
    writers: [Writers; 4],
    /// Remote writers on each input's topic, as discovery last said.
    listed: [u32; 4],
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

    /// Takes what arrived (at `now_ns` on the node's clock) from each input's own writer as its
    /// latest, refusing malformed and non-finite samples and other writers' samples (module
    /// docs); counts samples that did not decode. `listed`: the remote writers of each input's
    /// topic, as discovery last said; `silence_ns`: `--silence-ms`.
    pub fn update(
        &mut self,
        inputs: &Inputs,
        now_ns: u64,
        listed: [u32; 4],
        silence_ns: u64,
        counts: &mut FaultCounts,
    ) {
        self.listed = listed;
        for (w, n) in self.writers.iter_mut().zip(listed) {
            w.max_listed = w.max_listed.max(n);
        }
        let need = self.joints_needed;
        let all = if need >= 16 { u16::MAX } else { (1u16 << need) - 1 };
        let at = Arrival { now_ns, silence_ns };
        let [w_joints, w_base, w_tpose, w_ttwist] = &mut self.writers;
        at.take(&mut self.joints, w_joints, &inputs.joints, listed[0], Input::JointStates, counts, |s| {
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
        at.take(
            &mut self.base,
            w_base,
            &inputs.base,
            listed[1],
            Input::BasePose,
            counts,
            pose_check(Input::BasePose),
        );
        at.take(
            &mut self.target_pose,
            w_tpose,
            &inputs.target_pose,
            listed[2],
            Input::TargetPose,
            counts,
            pose_check(Input::TargetPose),
        );
        at.take(
            &mut self.target_twist,
            w_ttwist,
            &inputs.target_twist,
            listed[3],
            Input::TargetTwist,
            counts,
            |t| {
                if twist_finite(&t.twist) {
                    Ok(())
                } else {
                    Err(Fault::NonFinite(Input::TargetTwist))
                }
            },
        );
    }

    /// The inputs of a step at `now_mono_ns` (the node's clock) and `now_real_ns` (the system
    /// clock, ROS 2's time), or the first fault (module docs' order, inputs in
    /// [`Input::ALL`]'s).
    ///
    /// # Errors
    /// The [`Fault`] that gives the robot the zero command.
    pub fn check(&self, now_mono_ns: u64, now_real_ns: i64, ages: Ages) -> Result<Snapshot, Fault> {
        // A second writer first, then missing, then malformed or non-finite, over every input
        // before silence and age.
        let n = if self.target_read { 4 } else { 2 };
        for input in &Input::ALL[..n] {
            if self.second_writer(*input, now_mono_ns, ages.silence_ns).is_some() {
                return Err(Fault::SecondWriter(*input));
            }
        }
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

impl Latest {
    /// Whether `input` has a second writer at `now_ns` (module docs): `Some` with the other
    /// writer whose sample came last (`None` inside: only discovery lists it).
    pub fn second_writer(&self, input: Input, now_ns: u64, silence_ns: u64) -> Option<Option<WriterId>> {
        let w = &self.writers[input as usize];
        let recent = w.recent_other(now_ns, silence_ns);
        (recent.is_some() || self.listed[input as usize] > 1).then_some(recent)
    }

    /// Each input's writers.
    pub fn writers(&self) -> &[Writers; 4] {
        &self.writers
    }

    /// Each input's fault at `now_*` (`None`: good, or not read) — for naming every missing input
    /// when the node gives up waiting, not for the period.
    pub fn faults(&self, now_mono_ns: u64, now_real_ns: i64, ages: Ages) -> [Option<Fault>; 4] {
        let n = if self.target_read { 4 } else { 2 };
        let mut out = [None; 4];
        for input in &Input::ALL[..n] {
            // The check over this input alone: the others taken as good.
            let mut alone = *self;
            for other in &Input::ALL[..n] {
                if other != input {
                    alone.make_good(*other, now_mono_ns, now_real_ns);
                }
            }
            out[*input as usize] = alone.check(now_mono_ns, now_real_ns, ages).err();
        }
        out
    }

    /// `input` made a good, fresh sample (for [`Self::faults`]).
    fn make_good(&mut self, input: Input, now_mono_ns: u64, now_real_ns: i64) {
        let stamp = Time::from_ns(now_real_ns);
        let pose = StampedPose { stamp, pose: Pose::default() };
        let i = input as usize;
        self.writers[i].last_other = None;
        self.listed[i] = 0;
        match input {
            Input::JointStates => {
                let joints = [0.0; MAX_JOINTS];
                let v = JointSample { stamp, joints, found: u16::MAX, malformed: false };
                self.joints = Slot { value: Some(Ok(v)), arrived_ns: now_mono_ns };
            }
            Input::BasePose => self.base = Slot { value: Some(Ok(pose)), arrived_ns: now_mono_ns },
            Input::TargetPose => self.target_pose = Slot { value: Some(Ok(pose)), arrived_ns: now_mono_ns },
            Input::TargetTwist => {
                let v = StampedTwist { stamp, twist: Twist::default() };
                self.target_twist = Slot { value: Some(Ok(v)), arrived_ns: now_mono_ns };
            }
        }
    }
}

fn value<T: Copy>(slot: &Slot<T>, input: Input) -> Result<T, Fault> {
    match slot.value {
        None => Err(Fault::Missing(input)),
        Some(v) => v,
    }
}

/// When samples are taken, and the silence after which a writer is gone.
#[derive(Clone, Copy)]
struct Arrival {
    now_ns: u64,
    silence_ns: u64,
}

impl Arrival {
    /// The last sample of the input's own writer in `arrived` into `slot`, checked by `ok` (a
    /// refused one is counted); other writers' samples refused and noted in `w` (module docs).
    #[allow(clippy::too_many_arguments)]
    fn take<T: Copy>(
        self,
        slot: &mut Slot<T>,
        w: &mut Writers,
        arrived: &Arrived<T>,
        listed: u32,
        input: Input,
        counts: &mut FaultCounts,
        ok: impl Fn(&T) -> Result<(), Fault>,
    ) {
        let now_ns = self.now_ns;
        if arrived.undecodable > 0 {
            counts.undecodable[input as usize] += arrived.undecodable;
        }
        let own_gone = slot.value.is_none() || now_ns.saturating_sub(slot.arrived_ns) > self.silence_ns;
        // A writer is taken as the input's own when it is the only one: the only one that sent
        // samples now and lately, discovery listing one at most — and the input's own (if any)
        // is gone.
        if let (1, 0, Some((id, _))) = (arrived.writers(), arrived.overflow, arrived.by_writer[0]) {
            if listed <= 1 && own_gone && w.own != Some(id) && w.quiet_but(id, now_ns, self.silence_ns) {
                if w.own.is_some() {
                    w.adopted += 1;
                }
                w.own = Some(id);
            }
        }
        let mut own = None;
        for (s, n) in arrived.by_writer.iter().zip(arrived.samples) {
            match s {
                Some((id, v)) if Some(*id) == w.own => {
                    own = Some(*v);
                    w.own_samples += n;
                }
                Some((id, _)) => w.refuse(*id, n, now_ns),
                None => {}
            }
        }
        if arrived.overflow > 0 {
            w.others_overflow += arrived.overflow;
            w.last_other = Some((WriterId::default(), now_ns));
        }
        if let Some(v) = own {
            slot.arrived_ns = now_ns;
            slot.value = Some(ok(&v).map(|()| v));
        } else if arrived.undecodable > 0 && arrived.writers() == 0 {
            // The newest sample could not be read: what the robot sent last is unknown.
            slot.arrived_ns = now_ns;
            slot.value = Some(Err(Fault::Malformed(input)));
        }
    }
}

/// Periods answered with the zero command, by cause and input (`joint_states`,
/// `base_pose`, `target_pose`, `target_twist`), and undecodable samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FaultCounts {
    /// A second writer on the input.
    pub second_writer: [u64; 4],
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
            Fault::SecondWriter(i) => (&mut self.second_writer, i),
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
        [&self.second_writer, &self.missing, &self.malformed, &self.non_finite, &self.silent, &self.stale]
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

    const ROBOT: WriterId = WriterId([1; 16]);
    const ROGUE: WriterId = WriterId([2; 16]);

    fn arrived<T>(v: T) -> Arrived<T> {
        Arrived::one(ROBOT, v)
    }

    /// `update` with discovery listing the robot alone.
    fn up(l: &mut Latest, inputs: &Inputs, now_ns: u64, c: &mut FaultCounts) {
        l.update(inputs, now_ns, [1; 4], AGES.silence_ns, c);
    }

    fn inputs(j: JointSample, b: StampedPose) -> Inputs {
        Inputs { joints: arrived(j), base: arrived(b), ..Inputs::default() }
    }

    #[test]
    fn good_fresh_inputs_make_a_snapshot() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Missing(Input::JointStates)));
        up(&mut l, &inputs(joints(1_000_000, 0b11, [0.1, 0.2]), pose(1_000_000, 3.0)), 100, &mut c);
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
        up(&mut l, &inputs(joints(0, 0b01, [0.1, f64::NAN]), pose(0, 1.0)), 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Malformed(Input::JointStates)));
        // A good sample, then a non-finite one: the good one is not used again.
        up(&mut l, &inputs(joints(0, 0b11, [0.1, 0.2]), pose(0, 1.0)), 0, &mut c);
        assert!(l.check(0, 0, AGES).is_ok());
        let j = Inputs { joints: arrived(joints(0, 0b11, [0.1, f64::INFINITY])), ..Inputs::default() };
        up(&mut l, &j, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::NonFinite(Input::JointStates)));
        let b = Inputs {
            joints: arrived(joints(0, 0b11, [0.1, 0.2])),
            base: arrived(pose(0, f64::NAN)),
            ..Inputs::default()
        };
        up(&mut l, &b, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::NonFinite(Input::BasePose)));
        // A name listed twice.
        let mut dup = joints(0, 0b11, [0.1, 0.2]);
        dup.malformed = true;
        up(&mut l, &inputs(dup, pose(0, 1.0)), 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Malformed(Input::JointStates)));
        // An undecodable newest sample.
        let u = Inputs { joints: Arrived { undecodable: 2, ..Arrived::default() }, ..Inputs::default() };
        up(&mut l, &u, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Malformed(Input::JointStates)));
        assert_eq!(c.undecodable, [2, 0, 0, 0]);
    }

    #[test]
    fn silence_and_age_are_refused_at_their_limits() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        up(&mut l, &inputs(joints(10_000_000, 0b11, [0.1, 0.2]), pose(10_000_000, 1.0)), 1_000, &mut c);
        // Age: exactly max_age is good, one ns more is stale; a stamp from the future too.
        assert!(l.check(1_000, 15_000_000, AGES).is_ok());
        assert_eq!(l.check(1_000, 15_000_001, AGES), Err(Fault::Stale(Input::JointStates)));
        assert_eq!(l.check(1_000, 4_999_999, AGES), Err(Fault::Stale(Input::JointStates)));
        // Silence: on the node's clock, whatever the stamps say.
        assert!(l.check(20_001_000, 10_000_000, AGES).is_ok());
        assert_eq!(l.check(20_001_001, 10_000_000, AGES), Err(Fault::Silent(Input::JointStates)));
        // Only the base stale.
        let b = Inputs { base: arrived(pose(0, 1.0)), ..Inputs::default() };
        up(&mut l, &b, 1_000, &mut c);
        assert_eq!(l.check(1_000, 10_000_000, AGES), Err(Fault::Stale(Input::BasePose)));
    }

    #[test]
    fn the_target_read_from_topics_is_checked_as_the_robot_is() {
        let mut l = Latest::new(2, true);
        let mut c = FaultCounts::default();
        up(&mut l, &inputs(joints(0, 0b11, [0.1, 0.2]), pose(0, 1.0)), 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::Missing(Input::TargetPose)));
        let twist = StampedTwist { stamp: Time::from_ns(0), twist: Twist::default() };
        let t =
            Inputs { target_pose: arrived(pose(0, 2.0)), target_twist: arrived(twist), ..Inputs::default() };
        up(&mut l, &t, 0, &mut c);
        let s = l.check(0, 0, AGES).unwrap();
        assert_eq!(s.target.map(|(p, _)| p.pose.position.x), Some(2.0));
        let mut bad = twist;
        bad.twist.angular.z = f64::NAN;
        up(&mut l, &Inputs { target_twist: arrived(bad), ..Inputs::default() }, 0, &mut c);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::NonFinite(Input::TargetTwist)));
    }

    #[test]
    fn a_second_writer_is_refused_and_gives_the_zero_command_while_it_publishes() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        let good = |t: i64| inputs(joints(t, 0b11, [0.1, 0.2]), pose(t, 1.0));
        up(&mut l, &good(0), 0, &mut c);
        assert!(l.check(0, 0, AGES).is_ok());
        assert_eq!(l.writers()[0].own, Some(ROBOT));
        // The rogue's joint state right after the robot's, in the same read: refused, and the
        // period gets the zero command.
        let mut both = good(1_000_000);
        both.joints.push(ROGUE, joints(1_000_000, 0b11, [0.6, 0.7]));
        up(&mut l, &both, 1_000_000, &mut c);
        assert_eq!(l.check(1_000_000, 1_000_000, AGES), Err(Fault::SecondWriter(Input::JointStates)));
        assert_eq!(l.second_writer(Input::JointStates, 1_000_000, AGES.silence_ns), Some(Some(ROGUE)));
        // Alone in a read while the robot is still there: refused too, never the snapshot's.
        let rogue =
            Inputs { joints: Arrived::one(ROGUE, joints(2_000_000, 0b11, [0.6, 0.7])), ..Inputs::default() };
        up(&mut l, &rogue, 2_000_000, &mut c);
        assert_eq!(l.check(2_000_000, 2_000_000, AGES), Err(Fault::SecondWriter(Input::JointStates)));
        let w = l.writers()[0];
        assert_eq!(
            (w.own, w.own_samples, w.others[0].map(|o| (o.id, o.samples))),
            (Some(ROBOT), 2, Some((ROGUE, 2)))
        );
        // The rogue silent for --silence-ms: the robot's samples again, its own values.
        let t = 2_000_000 + AGES.silence_ns + 1;
        up(&mut l, &good(t as i64), t, &mut c);
        let s = l.check(t, t as i64, AGES).unwrap();
        assert_eq!(&s.joints[..2], &[0.1, 0.2]);
        // Discovery listing two writers on the base's topic: the zero command, with no sample of
        // the second.
        l.update(&good(t as i64), t, [1, 2, 0, 0], AGES.silence_ns, &mut c);
        assert_eq!(l.check(t, t as i64, AGES), Err(Fault::SecondWriter(Input::BasePose)));
        assert_eq!(l.second_writer(Input::BasePose, t, AGES.silence_ns), Some(None));
    }

    #[test]
    fn a_new_writer_is_taken_only_when_the_old_one_left_and_it_is_alone() {
        let mut l = Latest::new(2, false);
        let mut c = FaultCounts::default();
        // Two writers from the start: neither is taken.
        let mut both = inputs(joints(0, 0b11, [0.1, 0.2]), pose(0, 1.0));
        both.joints.push(ROGUE, joints(0, 0b11, [0.6, 0.7]));
        l.update(&both, 0, [2, 1, 0, 0], AGES.silence_ns, &mut c);
        assert_eq!(l.writers()[0].own, None);
        assert_eq!(l.check(0, 0, AGES), Err(Fault::SecondWriter(Input::JointStates)));
        // The robot alone, the other gone from discovery and silent: taken.
        let t = AGES.silence_ns + 1;
        let good = |t: u64| inputs(joints(t as i64, 0b11, [0.1, 0.2]), pose(t as i64, 1.0));
        l.update(&good(t), t, [1, 1, 0, 0], AGES.silence_ns, &mut c);
        assert_eq!(l.writers()[0].own, Some(ROBOT));
        assert!(l.check(t, t as i64, AGES).is_ok());
        // The robot's driver restarts: a new writer, alone, after the old one went silent and
        // left discovery — taken, and counted.
        let new = WriterId([3; 16]);
        let t2 = t + AGES.silence_ns + 1;
        let restarted = Inputs {
            joints: Arrived::one(new, joints(t2 as i64, 0b11, [0.3, 0.4])),
            base: arrived(pose(t2 as i64, 1.0)),
            ..Inputs::default()
        };
        l.update(&restarted, t2, [1, 1, 0, 0], AGES.silence_ns, &mut c);
        assert_eq!((l.writers()[0].own, l.writers()[0].adopted), (Some(new), 1));
        assert_eq!(&l.check(t2, t2 as i64, AGES).unwrap().joints[..2], &[0.3, 0.4]);
    }

    #[test]
    fn every_faulty_input_is_named_when_the_node_gives_up_waiting() {
        let mut l = Latest::new(2, true);
        let mut c = FaultCounts::default();
        up(&mut l, &Inputs { base: arrived(pose(0, 1.0)), ..Inputs::default() }, 0, &mut c);
        let f = l.faults(0, 0, AGES);
        assert_eq!(
            f,
            [
                Some(Fault::Missing(Input::JointStates)),
                None,
                Some(Fault::Missing(Input::TargetPose)),
                Some(Fault::Missing(Input::TargetTwist))
            ]
        );
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
