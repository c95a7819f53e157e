//! Runs replayable in Foxglove: a run written as an [MCAP](https://mcap.dev) file whose
//! channels use Foxglove's well-known schemas, so that opening the file in Foxglove shows the
//! robot moving in its 3D panel with no configuration.
//!
//! **Arm-agnostic.** The writer takes one [`ReplayFrame`] per logged step: the platform's
//! pose, every link's frame in its parent's frame, the end effector, the target, the joints,
//! the command and the tracking error, with names fixed once in a [`ReplayLayout`]. It knows
//! nothing of the planar RPR arm ([`super::replay`] turns a logged row of the planar path into
//! a frame); a spatial arm with six or seven joints feeds it the same way.
//!
//! **Channels** (message encoding `json`, schema encoding `jsonschema`; the schemas are
//! written here from Foxglove's published field lists):
//!
//! ```text
//! topic              schema                   what
//! /tf                foxglove.FrameTransforms world→base, base→link1→…→linkN→effector, world→target
//! /scene             foxglove.SceneUpdate     the platform (a nominal box), the arm as a line
//!                                             through its joints, the effector (a sphere), the
//!                                             target (a cube with its x, y, z axes as arrows)
//! /joint_states      foxglove.JointStates     each joint's name and position (rad or m)
//! /command           companion.Command        platform velocities by name, joint velocities by
//!                                             joint name, the step's status (ok, rejected:…,
//!                                             held, stopped)
//! /tracking_error    companion.TrackingError  e_p by component, ‖e_p‖, h_s
//! ```
//!
//! The command and the tracking error have no well-known Foxglove schema (the well-known
//! ones describe sensors and geometry, not a controller's internals), so they get schemas of
//! their own, named `companion.*`, with the components as named fields: Foxglove's Plot panel
//! takes `/tracking_error.e_p.x` or `/command.platform.v` directly. A value the law did not
//! produce (`h_s` of a rejected step) is JSON `null`.
//!
//! **Time.** Every message of a frame has the frame's time `t` (the run's time, from 0, in
//! nanoseconds) as its log and publish time and in its `timestamp`: the file is the same for
//! the same run, and Foxglove's timeline shows seconds since the run's start (as a date in
//! January 1970).
//!
//! **A failed run still leaves a readable file.** The file is finished (chunk, indexes,
//! summary and footer written) by [`McapRecorder::finish`], and if that is never reached — an
//! error part-way, a panic on the recording thread — when the recorder is dropped.

use std::fmt;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use companion_core::so3;
use companion_core::Pose3;
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;
use serde_json::{json, Value};

use super::output::{OutputDir, OutputError};

/// The names that stay the same over a run: frames, joints, components.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReplayLayout {
    /// The links' frame names, from the platform outwards: link `i`'s parent is link `i − 1`,
    /// the first link's is `base`.
    pub links: Vec<String>,
    /// The joints' names, in the order of [`ReplayFrame::joints`].
    pub joints: Vec<String>,
    /// The platform command's component names (e.g. `v`, `omega`), in the order of
    /// [`ReplayFrame::platform_command`].
    pub platform_command: Vec<String>,
    /// The tracking error's component names (e.g. `x`, `y`, `theta`), in the order of
    /// [`ReplayFrame::e_p`].
    pub e_p: Vec<String>,
}

/// One logged step, for any arm. Lengths must match the [`ReplayLayout`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayFrame<'a> {
    /// Time since the run's start (s, ≥ 0).
    pub t: f64,
    /// The platform in the world, `world_from_base` (on the ground: `z = 0`).
    pub base: Pose3<f64>,
    /// Each link's frame in its parent's frame, `parent_from_link` (the first link's parent
    /// is the platform).
    pub links: &'a [Pose3<f64>],
    /// The end effector in the last link's frame.
    pub effector: Pose3<f64>,
    /// The target in the world, `world_from_target`.
    pub target: Pose3<f64>,
    /// Joint positions (rad or m).
    pub joints: &'a [f64],
    /// The platform command (m/s, rad/s, 1/(m·s)).
    pub platform_command: &'a [f64],
    /// The joint velocity command (rad/s or m/s).
    pub joint_command: &'a [f64],
    /// The tracking error `e_p` by component (m, rad).
    pub e_p: &'a [f64],
    /// `‖e_p‖`.
    pub ep_norm: f64,
    /// `h_s` (NaN when the law gave none).
    pub h_s: f64,
    /// The step's status (`ok`, `rejected:…`, `held`, `stopped`).
    pub status: &'a str,
}

/// Why a replay file (`--mcap FILE`) could not be created or written.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A missing parent folder of the file cannot be made, or is not writable.
    #[error("--mcap: creating {}", path.display())]
    Folder {
        /// The file.
        path: PathBuf,
        /// Why the folder cannot be used.
        #[source]
        source: OutputError,
    },
    /// The file cannot be created.
    #[error("--mcap: creating {}", path.display())]
    Create {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// Writing the file's records failed.
    #[error("--mcap: writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The MCAP writer's error.
        #[source]
        source: ::mcap::McapError,
    },
    /// Writing the file's last bytes, or reading its size, failed.
    #[error("--mcap: writing {}", path.display())]
    Finish {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A channel's schema could not be formatted.
    #[error("a schema")]
    Schema(#[source] serde_json::Error),
    /// A message could not be formatted.
    #[error("formatting a replay message")]
    Message(#[source] serde_json::Error),
    /// A frame's field has another length than the layout's.
    #[error("{}: a frame has {got} {what}, the layout {want}", path.display())]
    Layout {
        /// The file.
        path: PathBuf,
        /// The field (`links`, `joints`, …).
        what: &'static str,
        /// The frame's length.
        got: usize,
        /// The layout's.
        want: usize,
    },
    /// A frame's time is not in `[0, 4e9)` s.
    #[error("{}: a frame's time must be in [0, 4e9) s, got {t}", path.display())]
    Time {
        /// The file.
        path: PathBuf,
        /// The frame's time (s).
        t: f64,
    },
}

/// The topics, in the order the channels are made.
pub const TOPICS: [&str; 5] = ["/tf", "/scene", "/joint_states", "/command", "/tracking_error"];

/// An MCAP file being written.
pub struct McapRecorder {
    writer: ::mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    layout: ReplayLayout,
    /// The folders made for the file (taken away by [`discard`](Self::discard)).
    made: Option<OutputDir>,
    /// Channel ids, in the order of [`TOPICS`].
    channels: [u16; 5],
    /// One reusable buffer for a message's JSON.
    buf: Vec<u8>,
    frames: u64,
}

impl fmt::Debug for McapRecorder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("McapRecorder").field("path", &self.path).field("frames", &self.frames).finish()
    }
}

/// What a finished file holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReplaySummary {
    /// The file.
    pub path: PathBuf,
    /// Frames written (each is one message on every topic).
    pub frames: u64,
    /// The file's size (bytes).
    pub bytes: u64,
}

/// The zstd level of the chunks: fast, and JSON of numbers shrinks ~5× already.
const ZSTD_LEVEL: u32 = 3;

impl McapRecorder {
    /// Creates `path` (and missing parent folders) and writes the header, schemas and
    /// channels. Called before the run starts, so that a path that cannot be written is an
    /// error before anything runs; the folders it made are taken away again if the file
    /// cannot be created.
    ///
    /// # Errors
    /// The file cannot be created or written.
    pub fn create(path: &Path, layout: ReplayLayout) -> Result<Self, ReplayError> {
        let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
        let made = parent
            .map(OutputDir::prepare)
            .transpose()
            .map_err(|source| ReplayError::Folder { path: path.to_path_buf(), source })?;
        let file = match File::create(path) {
            Ok(f) => f,
            Err(source) => {
                if let Some(d) = made {
                    d.discard();
                }
                return Err(ReplayError::Create { path: path.to_path_buf(), source });
            }
        };
        let options = ::mcap::WriteOptions::new()
            .compression(Some(::mcap::Compression::Zstd))
            .compression_level(ZSTD_LEVEL)
            // On the recording thread: no helper threads of zstd's own.
            .compression_threads(0)
            .profile("")
            .library(concat!("companion ", env!("CARGO_PKG_VERSION")));
        let mut writer = options.create(BufWriter::new(file)).map_err(writing(path))?;
        let mut channels = [0; 5];
        for (slot, (topic, (name, schema))) in channels.iter_mut().zip(TOPICS.iter().zip(schemas())) {
            let text = serde_json::to_vec(&schema).map_err(ReplayError::Schema)?;
            let schema_id = writer.add_schema(name, "jsonschema", &text).map_err(writing(path))?;
            *slot = writer
                .add_channel(schema_id, topic, "json", &std::collections::BTreeMap::new())
                .map_err(writing(path))?;
        }
        Ok(Self {
            writer,
            path: path.to_path_buf(),
            made,
            layout,
            channels,
            buf: Vec::with_capacity(4096),
            frames: 0,
        })
    }

    /// The run never started: removes the file and the folders made for it.
    pub fn discard(self) {
        let Self { writer, path, made, .. } = self;
        drop(writer);
        let _ = std::fs::remove_file(&path);
        if let Some(d) = made {
            d.discard();
        }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Writes one frame: one message on every topic.
    ///
    /// # Errors
    /// The frame does not match the layout, its time is not a finite non-negative number of
    /// seconds, or writing failed.
    pub fn write(&mut self, f: &ReplayFrame<'_>) -> Result<(), ReplayError> {
        let l = &self.layout;
        for (what, got, want) in [
            ("links", f.links.len(), l.links.len()),
            ("joints", f.joints.len(), l.joints.len()),
            ("joint_command", f.joint_command.len(), l.joints.len()),
            ("platform_command", f.platform_command.len(), l.platform_command.len()),
            ("e_p", f.e_p.len(), l.e_p.len()),
        ] {
            if got != want {
                return Err(ReplayError::Layout { path: self.path.clone(), what, got, want });
            }
        }
        if !(f.t.is_finite() && f.t >= 0.0 && f.t < 4.0e9) {
            return Err(ReplayError::Time { path: self.path.clone(), t: f.t });
        }
        let ns = (f.t * 1e9).round() as u64;
        let stamp = Stamp::of(ns);
        let messages = Messages { f, l: &self.layout, stamp };
        for (k, &channel_id) in self.channels.iter().enumerate() {
            self.buf.clear();
            messages.write(k, &mut self.buf).map_err(ReplayError::Message)?;
            let header = ::mcap::records::MessageHeader {
                channel_id,
                sequence: self.frames as u32,
                log_time: ns,
                publish_time: ns,
            };
            self.writer.write_to_known_channel(&header, &self.buf).map_err(writing(&self.path))?;
        }
        self.frames += 1;
        Ok(())
    }

    /// Writes the last chunk, the indexes, the summary and the footer.
    ///
    /// # Errors
    /// Writing failed.
    pub fn finish(mut self) -> Result<ReplaySummary, ReplayError> {
        self.writer.finish().map_err(writing(&self.path))?;
        let Self { writer, path, frames, .. } = self;
        // The buffer's last bytes, with their error (a drop would swallow it).
        let file = writer.into_inner().into_inner().map_err(std::io::IntoInnerError::into_error);
        let bytes = match file.and_then(|f| f.metadata()) {
            Ok(m) => m.len(),
            Err(source) => return Err(ReplayError::Finish { path, source }),
        };
        Ok(ReplaySummary { path, frames, bytes })
    }
}

/// The error of writing `path`'s records.
fn writing(path: &Path) -> impl Fn(::mcap::McapError) -> ReplayError + '_ {
    move |source| ReplayError::Write { path: path.to_path_buf(), source }
}

/// A time as Foxglove's JSON writes it.
#[derive(Clone, Copy, Debug, Serialize)]
struct Stamp {
    sec: u32,
    nsec: u32,
}

impl Stamp {
    fn of(ns: u64) -> Self {
        Self { sec: (ns / 1_000_000_000) as u32, nsec: (ns % 1_000_000_000) as u32 }
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
struct Vec3 {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Clone, Copy, Debug, Serialize)]
struct Quat {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

#[derive(Clone, Copy, Debug, Serialize)]
struct PoseMsg {
    position: Vec3,
    orientation: Quat,
}

#[derive(Clone, Copy, Debug, Serialize)]
struct Color {
    r: f64,
    g: f64,
    b: f64,
    a: f64,
}

fn vec3(v: &companion_core::nalgebra::Vector3<f64>) -> Vec3 {
    Vec3 { x: v[0], y: v[1], z: v[2] }
}

fn quat(p: &Pose3<f64>) -> Quat {
    let [x, y, z, w] = so3::to_quaternion(&p.rotation);
    Quat { x, y, z, w }
}

fn pose(p: &Pose3<f64>) -> PoseMsg {
    PoseMsg { position: vec3(&p.translation), orientation: quat(p) }
}

const IDENTITY: Quat = Quat { x: 0.0, y: 0.0, z: 0.0, w: 1.0 };

#[derive(Debug, Serialize)]
struct Transform<'a> {
    timestamp: Stamp,
    parent_frame_id: &'a str,
    child_frame_id: &'a str,
    translation: Vec3,
    rotation: Quat,
}

#[derive(Debug, Serialize)]
struct Transforms<'a> {
    transforms: Vec<Transform<'a>>,
}

#[derive(Debug, Serialize)]
struct Joint<'a> {
    name: &'a str,
    position: f64,
}

#[derive(Debug, Serialize)]
struct JointStates<'a> {
    timestamp: Stamp,
    joints: Vec<Joint<'a>>,
}

/// Values by name: a JSON object.
#[derive(Debug)]
struct Named<'a>(&'a [String], &'a [f64]);

impl Serialize for Named<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in self.0.iter().zip(self.1) {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

#[derive(Debug, Serialize)]
struct CommandMsg<'a> {
    timestamp: Stamp,
    platform: Named<'a>,
    joints: Named<'a>,
    status: &'a str,
}

#[derive(Debug, Serialize)]
struct ErrorMsg<'a> {
    timestamp: Stamp,
    e_p: Named<'a>,
    norm: f64,
    h_s: f64,
}

#[derive(Debug, Serialize)]
struct Cube {
    pose: PoseMsg,
    size: Vec3,
    color: Color,
}

#[derive(Debug, Serialize)]
struct Arrow {
    pose: PoseMsg,
    shaft_length: f64,
    shaft_diameter: f64,
    head_length: f64,
    head_diameter: f64,
    color: Color,
}

#[derive(Debug, Serialize)]
struct Line {
    /// 0: a line strip.
    #[serde(rename = "type")]
    kind: u8,
    pose: PoseMsg,
    thickness: f64,
    scale_invariant: bool,
    points: Vec<Vec3>,
    color: Color,
    colors: [Color; 0],
    indices: [u32; 0],
}

#[derive(Debug, Serialize)]
struct Entity<'a> {
    timestamp: Stamp,
    frame_id: &'a str,
    id: &'a str,
    lifetime: Stamp,
    frame_locked: bool,
    metadata: [(); 0],
    arrows: Vec<Arrow>,
    cubes: Vec<Cube>,
    spheres: Vec<Cube>,
    cylinders: [(); 0],
    lines: Vec<Line>,
    triangles: [(); 0],
    texts: [(); 0],
    models: [(); 0],
}

#[derive(Debug, Serialize)]
struct SceneUpdate<'a> {
    deletions: [(); 0],
    entities: [Entity<'a>; 2],
}

/// The platform's nominal box (m): the paper gives the platform no dimensions; this only
/// marks where it is and where it points.
const PLATFORM_BOX: Vec3 = Vec3 { x: 0.3, y: 0.2, z: 0.05 };
/// The target's cube and axes (m).
const TARGET_SIZE: f64 = 0.06;
const GREY: Color = Color { r: 0.55, g: 0.55, b: 0.6, a: 0.8 };
const GREEN: Color = Color { r: 0.1, g: 0.7, b: 0.2, a: 1.0 };
const BLUE: Color = Color { r: 0.15, g: 0.35, b: 0.95, a: 1.0 };
const RED: Color = Color { r: 0.9, g: 0.15, b: 0.1, a: 1.0 };

/// The messages of one frame.
struct Messages<'a, 'b> {
    f: &'a ReplayFrame<'b>,
    l: &'a ReplayLayout,
    stamp: Stamp,
}

impl Messages<'_, '_> {
    /// Message `k` (in the order of [`TOPICS`]) as JSON into `out`.
    fn write(&self, k: usize, out: &mut Vec<u8>) -> serde_json::Result<()> {
        match k {
            0 => serde_json::to_writer(out, &self.transforms()),
            1 => serde_json::to_writer(out, &self.scene()),
            2 => serde_json::to_writer(out, &self.joint_states()),
            3 => serde_json::to_writer(out, &self.command()),
            _ => serde_json::to_writer(out, &self.error()),
        }
    }

    fn transforms(&self) -> Transforms<'_> {
        let (f, l) = (self.f, self.l);
        let tf = |parent, child, p: &Pose3<f64>| Transform {
            timestamp: self.stamp,
            parent_frame_id: parent,
            child_frame_id: child,
            translation: vec3(&p.translation),
            rotation: quat(p),
        };
        let mut v = Vec::with_capacity(l.links.len() + 3);
        v.push(tf("world", "base", &f.base));
        let mut parent = "base";
        for (name, p) in l.links.iter().zip(f.links) {
            v.push(tf(parent, name, p));
            parent = name;
        }
        v.push(tf(parent, "effector", &f.effector));
        v.push(tf("world", "target", &f.target));
        Transforms { transforms: v }
    }

    fn joint_states(&self) -> JointStates<'_> {
        let joints =
            self.l.joints.iter().zip(self.f.joints).map(|(n, &q)| Joint { name: n, position: q }).collect();
        JointStates { timestamp: self.stamp, joints }
    }

    fn command(&self) -> CommandMsg<'_> {
        CommandMsg {
            timestamp: self.stamp,
            platform: Named(&self.l.platform_command, self.f.platform_command),
            joints: Named(&self.l.joints, self.f.joint_command),
            status: self.f.status,
        }
    }

    fn error(&self) -> ErrorMsg<'_> {
        ErrorMsg {
            timestamp: self.stamp,
            e_p: Named(&self.l.e_p, self.f.e_p),
            norm: self.f.ep_norm,
            h_s: self.f.h_s,
        }
    }

    fn scene(&self) -> SceneUpdate<'_> {
        let f = self.f;
        // The arm in the world: the platform's origin, each joint's origin, the effector.
        let mut world = f.base;
        let mut points = Vec::with_capacity(f.links.len() + 2);
        points.push(vec3(&world.translation));
        for link in f.links {
            world = world.compose(link);
            points.push(vec3(&world.translation));
        }
        let effector = world.compose(&f.effector);
        points.push(vec3(&effector.translation));
        // The box just below the arm's plane (the planar arm lies at z = 0).
        let mut box_pose = pose(&f.base);
        box_pose.position.z -= PLATFORM_BOX.z / 2.0 + 0.01;
        let entity = |id, arrows, cubes, spheres, lines| Entity {
            timestamp: self.stamp,
            frame_id: "world",
            id,
            lifetime: Stamp { sec: 0, nsec: 0 },
            frame_locked: false,
            metadata: [],
            arrows,
            cubes,
            spheres,
            cylinders: [],
            lines,
            triangles: [],
            texts: [],
            models: [],
        };
        let robot = entity(
            "robot",
            Vec::new(),
            vec![Cube { pose: box_pose, size: PLATFORM_BOX, color: GREY }],
            vec![Cube { pose: pose(&effector), size: Vec3 { x: 0.04, y: 0.04, z: 0.04 }, color: BLUE }],
            vec![Line {
                kind: 0,
                pose: PoseMsg { position: Vec3 { x: 0.0, y: 0.0, z: 0.0 }, orientation: IDENTITY },
                thickness: 0.02,
                scale_invariant: false,
                points,
                color: GREEN,
                colors: [],
                indices: [],
            }],
        );
        // The target: a cube and its axes x (red), y (green), z (blue).
        let s = TARGET_SIZE;
        let axis = |column: usize, color| {
            // The arrow points along the target's `column` axis: the target's rotation, then
            // a turn taking x onto that axis.
            let turn = match column {
                0 => companion_core::nalgebra::Matrix3::identity(),
                1 => so3::about_axis(2, 1.0, 0.0),
                _ => so3::about_axis(1, -1.0, 0.0),
            };
            let p = Pose3::new(f.target.rotation * turn, f.target.translation);
            Arrow {
                pose: pose(&p),
                shaft_length: 2.0 * s,
                shaft_diameter: s / 6.0,
                head_length: s / 2.0,
                head_diameter: s / 3.0,
                color,
            }
        };
        let target = entity(
            "target",
            vec![axis(0, RED), axis(1, GREEN), axis(2, BLUE)],
            vec![Cube { pose: pose(&f.target), size: Vec3 { x: s, y: s, z: s }, color: RED }],
            Vec::new(),
            Vec::new(),
        );
        SceneUpdate { deletions: [], entities: [robot, target] }
    }
}

// ---- The schemas (JSON Schema), written from Foxglove's published field lists. ----

fn number(description: &str) -> Value {
    json!({ "type": "number", "description": description })
}

fn string(description: &str) -> Value {
    json!({ "type": "string", "description": description })
}

fn boolean(description: &str) -> Value {
    json!({ "type": "boolean", "description": description })
}

fn object(title: &str, description: &str, properties: Value) -> Value {
    let required: Vec<String> =
        properties.as_object().map(|m| m.keys().cloned().collect()).unwrap_or_default();
    json!({ "title": title, "description": description, "type": "object", "properties": properties, "required": required })
}

fn time(description: &str) -> Value {
    json!({
        "type": "object", "title": "time", "description": description,
        "properties": {
            "sec": { "type": "integer", "minimum": 0 },
            "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 }
        },
        "required": ["sec", "nsec"]
    })
}

fn vector3(description: &str) -> Value {
    object(
        "foxglove.Vector3",
        description,
        json!({ "x": number("x (m)"), "y": number("y (m)"), "z": number("z (m)") }),
    )
}

fn quaternion(description: &str) -> Value {
    object(
        "foxglove.Quaternion",
        description,
        json!({ "x": number("x"), "y": number("y"), "z": number("z"), "w": number("w") }),
    )
}

fn pose_schema(description: &str) -> Value {
    object(
        "foxglove.Pose",
        description,
        json!({ "position": vector3("position"), "orientation": quaternion("orientation") }),
    )
}

fn color() -> Value {
    object(
        "foxglove.Color",
        "colour, each component in [0, 1]",
        json!({ "r": number("red"), "g": number("green"), "b": number("blue"), "a": number("opacity") }),
    )
}

fn array(items: Value, description: &str) -> Value {
    json!({ "type": "array", "items": items, "description": description })
}

fn unused(description: &str) -> Value {
    json!({ "type": "array", "description": format!("{description} (always empty here)") })
}

fn frame_transform() -> Value {
    object(
        "foxglove.FrameTransform",
        "where the child frame is in the parent frame",
        json!({
            "timestamp": time("time of the transform"),
            "parent_frame_id": string("parent frame"),
            "child_frame_id": string("child frame"),
            "translation": vector3("the child's origin in the parent frame"),
            "rotation": quaternion("the child's orientation in the parent frame")
        }),
    )
}

fn scene_update() -> Value {
    let primitive = |title: &str, description: &str, size: &str| {
        object(
            title,
            description,
            json!({ "pose": pose_schema("centre and orientation"), "size": vector3(size), "color": color() }),
        )
    };
    let arrow = object(
        "foxglove.ArrowPrimitive",
        "an arrow along its pose's x axis",
        json!({
            "pose": pose_schema("tail and orientation"),
            "shaft_length": number("shaft length (m)"),
            "shaft_diameter": number("shaft diameter (m)"),
            "head_length": number("head length (m)"),
            "head_diameter": number("head diameter (m)"),
            "color": color()
        }),
    );
    let line = object(
        "foxglove.LinePrimitive",
        "points joined by lines",
        json!({
            "type": { "type": "integer", "description": "0 line strip, 1 line loop, 2 line list" },
            "pose": pose_schema("origin of the points"),
            "thickness": number("thickness (m, or pixels if scale_invariant)"),
            "scale_invariant": boolean("thickness in pixels"),
            "points": array(object("foxglove.Point3", "a point", json!({ "x": number("x (m)"), "y": number("y (m)"), "z": number("z (m)") })), "the points"),
            "color": color(),
            "colors": array(color(), "per-point colours (empty: `color` for all)"),
            "indices": array(json!({ "type": "integer", "minimum": 0 }), "indices into points (empty: all in order)")
        }),
    );
    let entity = object(
        "foxglove.SceneEntity",
        "a drawn object, replaced by the next one with the same id",
        json!({
            "timestamp": time("time of the entity"),
            "frame_id": string("frame of the primitives' poses"),
            "id": string("identifier"),
            "lifetime": time("how long it stays (0: until replaced)"),
            "frame_locked": boolean("follows its frame"),
            "metadata": unused("key-value pairs"),
            "arrows": array(arrow, "arrows"),
            "cubes": array(primitive("foxglove.CubePrimitive", "a box", "edge lengths (m)"), "boxes"),
            "spheres": array(primitive("foxglove.SpherePrimitive", "a sphere", "diameters (m)"), "spheres"),
            "cylinders": unused("cylinders"),
            "lines": array(line, "lines"),
            "triangles": unused("triangle lists"),
            "texts": unused("texts"),
            "models": unused("models")
        }),
    );
    object(
        "foxglove.SceneUpdate",
        "entities of a 3D scene to add or replace",
        json!({ "deletions": unused("deletions"), "entities": array(entity, "entities") }),
    )
}

fn named_numbers(description: &str) -> Value {
    json!({
        "type": "object", "description": description,
        "additionalProperties": { "type": ["number", "null"] }
    })
}

/// `(schema name, JSON Schema)` of each topic, in the order of [`TOPICS`].
fn schemas() -> [(&'static str, Value); 5] {
    let transforms = object(
        "foxglove.FrameTransforms",
        "the robot's frames at one instant",
        json!({ "transforms": array(frame_transform(), "transforms") }),
    );
    let joint = json!({
        "title": "foxglove.JointState", "description": "one joint", "type": "object",
        "properties": {
            "name": string("joint name"),
            "position": number("position (rad for a revolute joint, m for a prismatic one)")
        },
        "required": ["name"]
    });
    let joint_states = object(
        "foxglove.JointStates",
        "the arm's joints at one instant",
        json!({ "timestamp": time("time"), "joints": array(joint, "joints") }),
    );
    let command = object(
        "companion.Command",
        "the command the controller gave for this step (held over the period)",
        json!({
            "timestamp": time("time of the measurement the command answers"),
            "platform": named_numbers("platform velocities by name: v (m/s), v_lat (m/s), omega (rad/s), v_xi (1/(m·s)), as the platform has them"),
            "joints": named_numbers("joint velocities by joint name (rad/s or m/s)"),
            "status": string("ok, rejected:<reason> (the safe zero command), held or stopped")
        }),
    );
    let error = object(
        "companion.TrackingError",
        "the true tracking error e_p = (r*_ed)⁻¹ r_ed of the paper's eq. (42), from the plant's state",
        json!({
            "timestamp": time("time"),
            "e_p": named_numbers("e_p by component (m, rad)"),
            "norm": { "type": ["number", "null"], "description": "‖e_p‖" },
            "h_s": { "type": ["number", "null"], "description": "the secondary task's h_s (null when the law rejected the step)" }
        }),
    );
    [
        ("foxglove.FrameTransforms", transforms),
        ("foxglove.SceneUpdate", scene_update()),
        ("foxglove.JointStates", joint_states),
        ("companion.Command", command),
        ("companion.TrackingError", error),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> ReplayLayout {
        let s = |v: &[&str]| v.iter().map(|x| (*x).to_string()).collect();
        ReplayLayout {
            links: s(&["l1", "l2"]),
            joints: s(&["a", "b"]),
            platform_command: s(&["v"]),
            e_p: s(&["x", "y", "z", "rx", "ry", "rz"]),
        }
    }

    fn path(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("companion-mcap-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d.join("sub/run.mcap")
    }

    /// Writes `n` frames of a two-joint spatial arm.
    fn write(r: &mut McapRecorder, n: u32) {
        let link = Pose3::from_xyz_rpy([0.1, 0.0, 0.3], [0.0, 0.5, 0.0]);
        for k in 0..n {
            let t = f64::from(k) * 0.25;
            let frame = ReplayFrame {
                t,
                base: Pose3::from_xyz_rpy([t, 0.0, 0.0], [0.0, 0.0, t]),
                links: &[link, link],
                effector: Pose3::translation(0.1, 0.0, 0.0),
                target: Pose3::translation(1.0, 2.0, 0.5),
                joints: &[t, -t],
                platform_command: &[1.0],
                joint_command: &[0.5, f64::NAN],
                e_p: &[0.0; 6],
                ep_norm: 0.0,
                h_s: f64::NAN,
                status: "ok",
            };
            r.write(&frame).unwrap();
        }
    }

    /// The messages of a file, per topic, read back with the `mcap` crate.
    fn read(p: &Path) -> std::collections::BTreeMap<String, Vec<(u64, Value)>> {
        let bytes = std::fs::read(p).unwrap();
        let summary =
            ::mcap::Summary::read(&bytes).unwrap().expect("a summary section: the file is finished");
        assert_eq!(summary.channels.len(), 5);
        let mut by_topic = std::collections::BTreeMap::<String, Vec<(u64, Value)>>::new();
        for m in ::mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            let v: Value = serde_json::from_slice(&m.data).unwrap();
            by_topic.entry(m.channel.topic.clone()).or_default().push((m.log_time, v));
        }
        by_topic
    }

    #[test]
    fn frames_become_one_message_per_topic_with_the_frames_time() {
        let p = path("frames");
        let mut r = McapRecorder::create(&p, layout()).unwrap();
        write(&mut r, 9);
        let s = r.finish().unwrap();
        assert_eq!(s.frames, 9);
        assert_eq!(s.bytes, std::fs::metadata(&p).unwrap().len());
        let m = read(&p);
        assert_eq!(m.keys().cloned().collect::<Vec<_>>(), {
            let mut t: Vec<String> = TOPICS.iter().map(|t| (*t).to_string()).collect();
            t.sort();
            t
        });
        for msgs in m.values() {
            assert_eq!(
                msgs.iter().map(|x| x.0).collect::<Vec<_>>(),
                (0..9u64).map(|k| k * 250_000_000).collect::<Vec<_>>()
            );
        }
        // The transform chain: world→base→l1→l2→effector, world→target.
        let tf = &m["/tf"][3].1["transforms"];
        let pairs: Vec<(String, String)> = tf
            .as_array()
            .unwrap()
            .iter()
            .map(|x| {
                (x["parent_frame_id"].as_str().unwrap().into(), x["child_frame_id"].as_str().unwrap().into())
            })
            .collect();
        let want = [("world", "base"), ("base", "l1"), ("l1", "l2"), ("l2", "effector"), ("world", "target")];
        assert_eq!(pairs, want.map(|(a, b)| (a.to_string(), b.to_string())));
        assert_eq!(tf[0]["timestamp"], json!({ "sec": 0, "nsec": 750_000_000 }));
        // The base turned by t = 0.75 about z.
        let q = &tf[0]["rotation"];
        assert!((q["z"].as_f64().unwrap() - (0.375f64).sin()).abs() < 1e-15, "{q}");
        // Values the law did not give are null; names are the layout's.
        let cmd = &m["/command"][1].1;
        assert_eq!(cmd["joints"], json!({ "a": 0.5, "b": null }));
        assert_eq!(m["/tracking_error"][0].1["h_s"], Value::Null);
        assert_eq!(m["/joint_states"][4].1["joints"][1], json!({ "name": "b", "position": -1.0 }));
        let _ = std::fs::remove_dir_all(p.parent().unwrap().parent().unwrap());
    }

    #[test]
    fn a_recorder_dropped_part_way_leaves_a_finished_file() {
        // What an error part-way (or a panic on the recording thread) does: no `finish`.
        let p = path("dropped");
        let mut r = McapRecorder::create(&p, layout()).unwrap();
        write(&mut r, 5);
        drop(r);
        let m = read(&p);
        assert!(m.values().all(|v| v.len() == 5), "{:?}", m.values().map(Vec::len).collect::<Vec<_>>());
        let _ = std::fs::remove_dir_all(p.parent().unwrap().parent().unwrap());
    }

    #[test]
    fn a_frame_that_does_not_match_the_layout_is_an_error() {
        let p = path("mismatch");
        let mut r = McapRecorder::create(&p, layout()).unwrap();
        let frame = ReplayFrame {
            t: 0.0,
            base: Pose3::identity(),
            links: &[Pose3::identity()],
            effector: Pose3::identity(),
            target: Pose3::identity(),
            joints: &[0.0, 0.0],
            platform_command: &[0.0],
            joint_command: &[0.0, 0.0],
            e_p: &[0.0; 6],
            ep_norm: 0.0,
            h_s: 0.0,
            status: "ok",
        };
        let e = r.write(&frame).unwrap_err();
        assert!(format!("{e:#}").contains("a frame has 1 links, the layout 2"), "{e:#}");
        let e = r.write(&ReplayFrame { t: f64::NAN, links: &[Pose3::identity(); 2], ..frame }).unwrap_err();
        assert!(format!("{e:#}").contains("time must be in [0, 4e9) s, got NaN"), "{e:#}");
        assert_eq!(r.finish().unwrap().frames, 0);
        let _ = std::fs::remove_dir_all(p.parent().unwrap().parent().unwrap());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_path_that_cannot_be_written_is_an_error_naming_it() {
        for bad in ["/proc/companion-replay.mcap", "/proc/companion-no-such-dir/run.mcap"] {
            let e = McapRecorder::create(Path::new(bad), layout()).unwrap_err();
            let text = format!("{e:#}");
            assert!(text.contains("--mcap") && text.contains(bad), "{text}");
        }
    }
}
