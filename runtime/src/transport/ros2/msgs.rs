//! ROS 2's messages as their CDR layout on the wire (what `rmw_cyclonedds` and `rmw_fastrtps`
//! exchange): each struct's fields in the order of its `.msg` file, `std_msgs/Header` first
//! where the message has one. Serde's field order is the CDR order; fixed arrays (`float64[36]`)
//! are CDR arrays (no length), unbounded arrays (`float64[]`, `string[]`) CDR sequences (a
//! `uint32` length first). The DDS type name of `pkg/Type` is `pkg::msg::dds_::Type_`
//! ([`Ros2Type`]).
//!
//! The messages the node *receives* are read into fixed storage: a `sensor_msgs/JointState`
//! through [`JointStateSeed`], which takes the positions of the arm's joints by name into an
//! array (no allocation of the node's; RustDDS allocates the sample's bytes). The messages it
//! *sends* on every period ([`TwistStampedOut`], [`TwistOut`], [`JointVelocities`],
//! [`PoseStampedOut`]) serialise from fixed storage too; the diagnostics
//! ([`DiagnosticArray`]) are made off the control thread.

use std::sync::Arc;

use serde::de::{self, DeserializeSeed, SeqAccess, Visitor};
use serde::ser::{SerializeStruct, SerializeTuple};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A ROS 2 message type: its package and name (`sensor_msgs`, `JointState`).
pub trait Ros2Type {
    /// The package.
    const PACKAGE: &'static str;
    /// The type's name.
    const NAME: &'static str;

    /// The DDS type name, `pkg::msg::dds_::Type_`.
    fn dds_type_name() -> String {
        format!("{}::msg::dds_::{}_", Self::PACKAGE, Self::NAME)
    }
}

macro_rules! ros2_type {
    ($t:ty, $pkg:literal, $name:literal) => {
        impl Ros2Type for $t {
            const PACKAGE: &'static str = $pkg;
            const NAME: &'static str = $name;
        }
    };
}

/// `builtin_interfaces/Time`: `int32 sec`, `uint32 nanosec`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds, `[0, 10⁹)`.
    pub nanosec: u32,
}

impl Time {
    /// The time of `ns` nanoseconds since the epoch (saturating at `int32`'s seconds).
    pub fn from_ns(ns: i64) -> Self {
        let sec = ns.div_euclid(1_000_000_000);
        Self {
            sec: i32::try_from(sec).unwrap_or(if sec < 0 { i32::MIN } else { i32::MAX }),
            nanosec: u32::try_from(ns.rem_euclid(1_000_000_000)).unwrap_or(0),
        }
    }

    /// Nanoseconds since the epoch.
    pub fn as_ns(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/Header`: `builtin_interfaces/Time stamp`, `string frame_id`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// The stamp.
    pub stamp: Time,
    /// The frame.
    pub frame_id: String,
}
ros2_type!(Header, "std_msgs", "Header");

/// `geometry_msgs/Vector3` and `geometry_msgs/Point`: `float64 x, y, z`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`: `float64 x, y, z, w`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }
    }
}

/// `geometry_msgs/Pose`: `Point position`, `Quaternion orientation`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// The position (m).
    pub position: Vector3,
    /// The orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/Twist`: `Vector3 linear`, `Vector3 angular`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// m/s.
    pub linear: Vector3,
    /// rad/s.
    pub angular: Vector3,
}
ros2_type!(Twist, "geometry_msgs", "Twist");

/// `float64[36]`: a 6×6 covariance, row by row (a CDR array: no length on the wire).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Self([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for x in &self.0 {
            t.serialize_element(x)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, x) in c.iter_mut().enumerate() {
                    *x = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// `geometry_msgs/PoseWithCovariance`: `Pose pose`, `float64[36] covariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `geometry_msgs/TwistWithCovariance`: `Twist twist`, `float64[36] covariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `nav_msgs/Odometry`: `Header header`, `string child_frame_id`, `PoseWithCovariance pose`,
/// `TwistWithCovariance twist`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and the pose's frame (`odom`).
    pub header: Header,
    /// The twist's frame (`base_link`).
    pub child_frame_id: String,
    /// The platform's pose.
    pub pose: PoseWithCovariance,
    /// Its velocity.
    pub twist: TwistWithCovariance,
}
ros2_type!(Odometry, "nav_msgs", "Odometry");

/// `geometry_msgs/PoseStamped`: `Header header`, `Pose pose`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}
ros2_type!(PoseStamped, "geometry_msgs", "PoseStamped");

/// `geometry_msgs/TwistStamped`: `Header header`, `Twist twist`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The twist.
    pub twist: Twist,
}
ros2_type!(TwistStamped, "geometry_msgs", "TwistStamped");

/// `sensor_msgs/JointState`: `Header header`, `string[] name`, `float64[] position`,
/// `float64[] velocity`, `float64[] effort` (the whole message, for tests and tools; the node
/// reads it through [`JointStateSeed`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp and frame.
    pub header: Header,
    /// The joints' names.
    pub name: Vec<String>,
    /// Their positions (rad or m).
    pub position: Vec<f64>,
    /// Their velocities (may be empty).
    pub velocity: Vec<f64>,
    /// Their efforts (may be empty).
    pub effort: Vec<f64>,
}
ros2_type!(JointState, "sensor_msgs", "JointState");

/// `std_msgs/MultiArrayDimension`: `string label`, `uint32 size`, `uint32 stride`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// The dimension's label.
    pub label: String,
    /// Its size.
    pub size: u32,
    /// Its stride.
    pub stride: u32,
}

/// `std_msgs/MultiArrayLayout`: `MultiArrayDimension[] dim`, `uint32 data_offset`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    /// The dimensions (none: a flat array, as `JointGroupVelocityController` reads it).
    pub dim: Vec<MultiArrayDimension>,
    /// The offset of the first element.
    pub data_offset: u32,
}

/// `std_msgs/Float64MultiArray`: `MultiArrayLayout layout`, `float64[] data`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Float64MultiArray {
    /// The layout.
    pub layout: MultiArrayLayout,
    /// The values.
    pub data: Vec<f64>,
}
ros2_type!(Float64MultiArray, "std_msgs", "Float64MultiArray");

/// `diagnostic_msgs/KeyValue`: `string key`, `string value`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    /// The key.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

/// `diagnostic_msgs/DiagnosticStatus`: `byte level`, `string name`, `string message`,
/// `string hardware_id`, `KeyValue[] values` (levels: 0 OK, 1 WARN, 2 ERROR, 3 STALE).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    pub level: u8,
    /// The reporting component.
    pub name: String,
    /// One line.
    pub message: String,
    /// The hardware.
    pub hardware_id: String,
    /// The figures.
    pub values: Vec<KeyValue>,
}

/// `diagnostic_msgs/DiagnosticArray`: `Header header`, `DiagnosticStatus[] status`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp.
    pub header: Header,
    /// One status per component.
    pub status: Vec<DiagnosticStatus>,
}
ros2_type!(DiagnosticArray, "diagnostic_msgs", "DiagnosticArray");

/// A header from fixed storage: the stamp and a frame shared by every message (an `Arc`:
/// cloning it allocates nothing).
#[derive(Clone, Debug)]
pub struct HeaderOut {
    /// The stamp.
    pub stamp: Time,
    /// The frame.
    pub frame_id: Arc<str>,
}

impl Serialize for HeaderOut {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("Header", 2)?;
        st.serialize_field("stamp", &self.stamp)?;
        st.serialize_field("frame_id", &*self.frame_id)?;
        st.end()
    }
}

/// `geometry_msgs/TwistStamped` as the node sends it (the base command; Jazzy's
/// `diff_drive_controller` reads this on `~/cmd_vel`).
#[derive(Clone, Debug, Serialize)]
pub struct TwistStampedOut {
    /// Stamp and the platform's frame.
    pub header: HeaderOut,
    /// The command.
    pub twist: Twist,
}
ros2_type!(TwistStampedOut, "geometry_msgs", "TwistStamped");

/// `geometry_msgs/Twist` as the node sends it (`--twist-unstamped`: Humble's controllers).
pub type TwistOut = Twist;

/// `geometry_msgs/PoseStamped` as the node sends it (the target it generates).
#[derive(Clone, Debug, Serialize)]
pub struct PoseStampedOut {
    /// Stamp and the world frame.
    pub header: HeaderOut,
    /// The pose.
    pub pose: Pose,
}
ros2_type!(PoseStampedOut, "geometry_msgs", "PoseStamped");

/// The most joint velocities the node sends in one `Float64MultiArray`.
pub const MAX_COMMAND_JOINTS: usize = 32;

/// `std_msgs/Float64MultiArray` from fixed storage, with no dimensions (a flat array, what
/// `forward_command_controller`'s `JointGroupVelocityController` reads on `~/commands`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointVelocities {
    /// The values; the first `len` are sent.
    pub data: [f64; MAX_COMMAND_JOINTS],
    /// How many.
    pub len: usize,
}

impl Serialize for JointVelocities {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        struct FlatLayout;
        impl Serialize for FlatLayout {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                let mut st = s.serialize_struct("MultiArrayLayout", 2)?;
                st.serialize_field("dim", &[] as &[MultiArrayDimension])?;
                st.serialize_field("data_offset", &0u32)?;
                st.end()
            }
        }
        let mut st = s.serialize_struct("Float64MultiArray", 2)?;
        st.serialize_field("layout", &FlatLayout)?;
        st.serialize_field("data", &self.data[..self.len.min(MAX_COMMAND_JOINTS)])?;
        st.end()
    }
}
ros2_type!(JointVelocities, "std_msgs", "Float64MultiArray");

/// The most joints a `JointState` may list for the node to read it (a robot's whole state:
/// arm, torso, head, grippers, wheels).
pub const MAX_LISTED_JOINTS: usize = 64;

/// What the node takes of one `sensor_msgs/JointState`: its stamp, and the positions of the
/// arm's joints found by name (`joints[i]` for the arm's joint `i`, `found` bit `i`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointSample {
    /// The header's stamp.
    pub stamp: Time,
    /// The arm's joints' positions, in the arm's order (NaN where not found).
    pub joints: [f64; crate::domain::arm::MAX_JOINTS],
    /// Bit `i`: the arm's joint `i` was listed.
    pub found: u16,
    /// A joint of the arm listed twice, more names than [`MAX_LISTED_JOINTS`], or fewer
    /// positions than names: the message is malformed.
    pub malformed: bool,
}

/// A `sensor_msgs/JointState` decoder into a [`JointSample`], by the arm's joint names: names
/// the arm does not have are skipped, positions beyond the names ignored.
#[derive(Clone, Copy, Debug)]
pub struct JointStateSeed<'a> {
    /// The arm's joint names, in its order.
    pub names: &'a [String],
}

impl<'de> DeserializeSeed<'de> for JointStateSeed<'_> {
    type Value = JointSample;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<JointSample, D::Error> {
        d.deserialize_struct("JointState", &["header", "name", "position", "velocity", "effort"], self)
    }
}

impl<'de> Visitor<'de> for JointStateSeed<'_> {
    type Value = JointSample;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("sensor_msgs/JointState")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<JointSample, A::Error> {
        let header: HeaderStamp = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(0, &self))?;
        let mut map = NameMap { slot: [u8::MAX; MAX_LISTED_JOINTS], listed: 0, duplicate: false, found: 0 };
        seq.next_element_seed(NamesSeed { names: self.names, map: &mut map })?
            .ok_or_else(|| de::Error::invalid_length(1, &self))?;
        let mut sample = JointSample {
            stamp: header.0,
            joints: [f64::NAN; crate::domain::arm::MAX_JOINTS],
            found: map.found,
            malformed: map.duplicate || map.listed > MAX_LISTED_JOINTS,
        };
        let positions = seq
            .next_element_seed(PositionsSeed { map: &map, joints: &mut sample.joints })?
            .ok_or_else(|| de::Error::invalid_length(2, &self))?;
        if positions < map.listed.min(MAX_LISTED_JOINTS) {
            sample.malformed = true;
        }
        // velocity and effort: read past (their values are not used).
        for i in 3..5 {
            seq.next_element::<Skipped>()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        Ok(sample)
    }
}

/// A header read for its stamp only (the frame is read past).
pub(crate) struct HeaderStamp(pub(crate) Time);

impl<'de> Deserialize<'de> for HeaderStamp {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = HeaderStamp;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("std_msgs/Header")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<HeaderStamp, A::Error> {
                let stamp = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(0, &self))?;
                seq.next_element::<Ignored>()?.ok_or_else(|| de::Error::invalid_length(1, &self))?;
                Ok(HeaderStamp(stamp))
            }
        }
        d.deserialize_struct("Header", &["stamp", "frame_id"], V)
    }
}

/// A string read past.
pub(crate) struct Ignored;

impl<'de> Deserialize<'de> for Ignored {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Ignored;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a string")
            }
            fn visit_str<E: de::Error>(self, _: &str) -> Result<Ignored, E> {
                Ok(Ignored)
            }
        }
        d.deserialize_str(V)
    }
}

/// A `float64[]` read past.
struct Skipped;

impl<'de> Deserialize<'de> for Skipped {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Skipped;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("float64[]")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Skipped, A::Error> {
                while seq.next_element::<f64>()?.is_some() {}
                Ok(Skipped)
            }
        }
        d.deserialize_seq(V)
    }
}

/// Where each listed name goes: `slot[k]` is the arm's joint of the message's `k`-th name
/// (`u8::MAX`: not the arm's).
struct NameMap {
    slot: [u8; MAX_LISTED_JOINTS],
    listed: usize,
    duplicate: bool,
    found: u16,
}

struct NamesSeed<'a, 'm> {
    names: &'a [String],
    map: &'m mut NameMap,
}

impl<'de> DeserializeSeed<'de> for NamesSeed<'_, '_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for NamesSeed<'_, '_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("string[]")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        loop {
            let k = self.map.listed;
            let which = seq.next_element_seed(NameSeed { names: self.names })?;
            let Some(which) = which else { return Ok(()) };
            self.map.listed += 1;
            let Some(slot) = self.map.slot.get_mut(k) else { continue };
            if let Some(i) = which {
                let bit = 1u16 << i;
                if self.map.found & bit != 0 {
                    self.map.duplicate = true;
                }
                self.map.found |= bit;
                *slot = i;
            }
        }
    }
}

/// One name: the index of the arm's joint of that name, if any.
#[derive(Clone, Copy)]
struct NameSeed<'a> {
    names: &'a [String],
}

impl<'de> DeserializeSeed<'de> for NameSeed<'_> {
    type Value = Option<u8>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Option<u8>, D::Error> {
        d.deserialize_str(self)
    }
}

impl Visitor<'_> for NameSeed<'_> {
    type Value = Option<u8>;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a joint name")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<Option<u8>, E> {
        // ROS 2's strings on the wire may carry their terminating NUL into the decoded text
        // with some decoders: compare without it.
        let v = v.strip_suffix('\0').unwrap_or(v);
        Ok(self.names.iter().position(|n| n == v).and_then(|i| u8::try_from(i).ok()))
    }
}

struct PositionsSeed<'m, 'j> {
    map: &'m NameMap,
    joints: &'j mut [f64; crate::domain::arm::MAX_JOINTS],
}

impl<'de> DeserializeSeed<'de> for PositionsSeed<'_, '_> {
    type Value = usize;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<usize, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for PositionsSeed<'_, '_> {
    type Value = usize;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("float64[]")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<usize, A::Error> {
        let mut k = 0;
        while let Some(x) = seq.next_element::<f64>()? {
            if let Some(&i) = self.map.slot.get(k) {
                if let Some(q) = self.joints.get_mut(usize::from(i)) {
                    *q = x;
                }
            }
            k += 1;
        }
        Ok(k)
    }
}

/// The stamp of a message and its pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampedPose {
    /// The header's stamp.
    pub stamp: Time,
    /// The pose.
    pub pose: Pose,
}

/// The stamp of a message and its twist.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampedTwist {
    /// The header's stamp.
    pub stamp: Time,
    /// The twist.
    pub twist: Twist,
}

/// `nav_msgs/Odometry` read for its stamp and pose (the frames and the twist read past).
pub(crate) struct OdometryIn(pub(crate) StampedPose);

/// `geometry_msgs/PoseStamped` read for its stamp and pose.
pub(crate) struct PoseStampedIn(pub(crate) StampedPose);

/// `geometry_msgs/TwistStamped` read for its stamp and twist.
pub(crate) struct TwistStampedIn(pub(crate) StampedTwist);

fn next<'de, A: SeqAccess<'de>, T: Deserialize<'de>>(
    seq: &mut A,
    i: usize,
    exp: &dyn de::Expected,
) -> Result<T, A::Error> {
    seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, exp))
}

/// The `Deserialize` of a stamped message read into fixed storage: its header's stamp, then
/// `$body` reads the rest.
macro_rules! stamped_in {
    ($t:ident, $name:literal, [$($field:literal),*], |$seq:ident, $stamp:ident, $exp:ident| $body:expr) => {
        impl<'de> Deserialize<'de> for $t {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                struct V;
                impl<'de> Visitor<'de> for V {
                    type Value = $t;
                    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                        f.write_str($name)
                    }
                    fn visit_seq<A: SeqAccess<'de>>(self, mut $seq: A) -> Result<$t, A::Error> {
                        let $exp: &dyn de::Expected = &self;
                        let HeaderStamp($stamp) = next(&mut $seq, 0, $exp)?;
                        $body
                    }
                }
                d.deserialize_struct($name, &[$($field),*], V)
            }
        }
    };
}

stamped_in!(OdometryIn, "Odometry", ["header", "child_frame_id", "pose", "twist"], |seq, stamp, exp| {
    let _: Ignored = next(&mut seq, 1, exp)?;
    let pose: PoseWithCovariance = next(&mut seq, 2, exp)?;
    let _: TwistWithCovariance = next(&mut seq, 3, exp)?;
    Ok(OdometryIn(StampedPose { stamp, pose: pose.pose }))
});

stamped_in!(PoseStampedIn, "PoseStamped", ["header", "pose"], |seq, stamp, exp| {
    let pose: Pose = next(&mut seq, 1, exp)?;
    Ok(PoseStampedIn(StampedPose { stamp, pose }))
});

stamped_in!(TwistStampedIn, "TwistStamped", ["header", "twist"], |seq, stamp, exp| {
    let twist: Twist = next(&mut seq, 1, exp)?;
    Ok(TwistStampedIn(StampedTwist { stamp, twist }))
});
