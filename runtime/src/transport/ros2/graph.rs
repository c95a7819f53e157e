//! The graph as the node needs it: which DDS writers publish on each of its input topics (DDS
//! discovery, SEDP), and the ROS node behind each writer (ROS 2's `ros_discovery_info`, where
//! every `rmw` lists its nodes' readers and writers by GID).
//!
//! A thread of its own ([`Graph::spawn`]) polls RustDDS's discovered writers every
//! [`POLL`] and reads `ros_discovery_info`; it publishes, per input, the number of remote
//! writers of the input's topic and type to an atomic the node's period reads (no lock, no
//! allocation), and keeps the writer → node names for the messages and the summary (a mutex,
//! off the node's period).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ros2_client::dds::rustdds::{self, no_key::DataReader, CDRDeserializerAdapter, RTPSEntity, TopicKind};
use serde::Deserialize;

/// How often the discovered writers are read.
pub const POLL: Duration = Duration::from_millis(5);

/// A DDS writer's GUID (16 bytes: the participant's prefix, then the entity), as ROS 2 calls it
/// a GID.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct WriterId(pub [u8; 16]);

impl std::fmt::Display for WriterId {
    /// As `ros2 topic info --verbose` prints a GID: the bytes in hex, joined by dots.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(".")?;
            }
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl From<rustdds::GUID> for WriterId {
    fn from(g: rustdds::GUID) -> Self {
        let b = g.to_bytes();
        let mut out = [0; 16];
        out.copy_from_slice(&b[..16]);
        Self(out)
    }
}

impl From<ros2_client::Gid> for WriterId {
    fn from(g: ros2_client::Gid) -> Self {
        Self(g.to_bytes16())
    }
}

/// `rmw_dds_common/msg/Gid` (Iron and later): `char[16] data`.
#[derive(Clone, Copy, Debug, Deserialize)]
struct GidMsg {
    data: [u8; 16],
}

/// `rmw_dds_common/msg/NodeEntitiesInfo`.
#[derive(Clone, Debug, Deserialize)]
struct NodeEntitiesInfoMsg {
    node_namespace: String,
    node_name: String,
    _reader_gid_seq: Vec<GidMsg>,
    writer_gid_seq: Vec<GidMsg>,
}

/// `rmw_dds_common/msg/ParticipantEntitiesInfo`: a participant's nodes and their endpoints.
#[derive(Clone, Debug, Deserialize)]
struct ParticipantEntitiesInfoMsg {
    _gid: GidMsg,
    node_entities_info_seq: Vec<NodeEntitiesInfoMsg>,
}

/// What the graph thread shares.
#[derive(Debug, Default)]
struct Shared {
    /// Remote writers of each input's topic and type.
    counts: [AtomicU32; 4],
    /// The node behind each writer that a `ros_discovery_info` ever named (`/ns/name`).
    nodes: Mutex<BTreeMap<WriterId, String>>,
    /// The remote writers of each input, as last polled.
    writers: Mutex<[Vec<WriterId>; 4]>,
    /// Every remote writer discovery ever listed on each input.
    ever: Mutex<[Vec<WriterId>; 4]>,
}

/// The graph thread and what it found.
#[derive(Debug)]
pub struct Graph {
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// An input topic the graph watches: its DDS topic and type name (`None`: the input is not read).
pub type Watched = [Option<(String, String)>; 4];

impl Graph {
    /// Starts the graph thread on `participant`, watching `inputs` (in the order of the node's
    /// inputs: joint states, base pose, target pose, target twist).
    ///
    /// # Errors
    /// The `ros_discovery_info` reader or the thread could not be made.
    pub fn spawn(participant: &rustdds::DomainParticipant, inputs: Watched) -> Result<Self, String> {
        // Transient local, as the rmw's write it: a participant's info written before this
        // reader matched is still read (ros2-client's own reader is volatile and misses it).
        let sub_qos = rustdds::QosPolicyBuilder::new()
            .durability(rustdds::policy::Durability::TransientLocal)
            .reliable(rustdds::Duration::ZERO)
            .history(rustdds::policy::History::KeepLast { depth: 100 })
            .build();
        let subscriber = participant.create_subscriber(&sub_qos).map_err(|e| format!("{e:?}"))?;
        let topic = participant
            .create_topic(
                ros2_client::builtin_topics::ros_discovery::TOPIC_NAME.to_string(),
                ros2_client::builtin_topics::ros_discovery::TYPE_NAME.to_string(),
                &sub_qos,
                TopicKind::NoKey,
            )
            .map_err(|e| format!("{e:?}"))?;
        let reader: DataReader<ParticipantEntitiesInfoMsg, CDRDeserializerAdapter<_>> =
            subscriber.create_datareader_no_key_cdr(&topic, Some(sub_qos)).map_err(|e| format!("{e:?}"))?;
        let shared = Arc::new(Shared::default());
        let stop = Arc::new(AtomicBool::new(false));
        let own = prefix(participant.guid());
        let dp = participant.clone();
        let (s, st) = (Arc::clone(&shared), Arc::clone(&stop));
        let thread = std::thread::Builder::new()
            .name("ros2-graph".into())
            .spawn(move || watch(&dp, own, reader, &inputs, &s, &st))
            .map_err(|e| e.to_string())?;
        Ok(Self { shared, stop, thread: Some(thread) })
    }

    /// The number of remote writers of each input's topic and type, as last polled (no lock).
    pub fn counts(&self) -> [u32; 4] {
        std::array::from_fn(|i| self.shared.counts[i].load(Ordering::Relaxed))
    }

    /// The ROS node behind `writer` (`/ns/name`), if a `ros_discovery_info` named it.
    pub fn node_of(&self, writer: WriterId) -> Option<String> {
        self.shared.nodes.lock().ok()?.get(&writer).cloned()
    }

    /// The remote writers of input `i`, as last polled.
    pub fn writers(&self, i: usize) -> Vec<WriterId> {
        self.shared.writers.lock().map(|w| w[i].clone()).unwrap_or_default()
    }

    /// Every remote writer discovery listed on input `i` while the node ran.
    pub fn ever(&self, i: usize) -> Vec<WriterId> {
        self.shared.ever.lock().map(|w| w[i].clone()).unwrap_or_default()
    }

    /// A handle that names writers, for another thread.
    pub fn names(&self) -> GraphNames {
        GraphNames { shared: Arc::clone(&self.shared) }
    }
}

/// Names writers from another thread ([`Graph::names`]).
#[derive(Clone, Debug)]
pub struct GraphNames {
    shared: Arc<Shared>,
}

impl GraphNames {
    /// As [`Graph::node_of`].
    pub fn node_of(&self, writer: WriterId) -> Option<String> {
        self.shared.nodes.lock().ok()?.get(&writer).cloned()
    }
}

impl Drop for Graph {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A GUID's participant prefix (its first 12 bytes).
fn prefix(g: rustdds::GUID) -> [u8; 12] {
    let mut p = [0; 12];
    p.copy_from_slice(&g.to_bytes()[..12]);
    p
}

fn watch(
    dp: &rustdds::DomainParticipant,
    own: [u8; 12],
    mut reader: DataReader<ParticipantEntitiesInfoMsg, CDRDeserializerAdapter<ParticipantEntitiesInfoMsg>>,
    inputs: &Watched,
    shared: &Shared,
    stop: &AtomicBool,
) {
    while !stop.load(Ordering::Relaxed) {
        // Every writer a participant's ros_discovery_info ever named keeps its node (GUIDs are
        // not reused): a writer that left is still named in the summary.
        while let Ok(Some(s)) = reader.take_next_sample() {
            let info = s.into_value();
            if let Ok(mut m) = shared.nodes.lock() {
                for n in &info.node_entities_info_seq {
                    let ns = n.node_namespace.trim_end_matches('/');
                    let name = format!("{ns}/{}", n.node_name);
                    m.extend(n.writer_gid_seq.iter().map(|g| (WriterId(g.data), name.clone())));
                }
            }
        }
        let found = dp.discovered_writers();
        let mut now: [Vec<WriterId>; 4] = Default::default();
        for (i, watched) in inputs.iter().enumerate() {
            let Some((topic, typ)) = watched else { continue };
            for w in &found {
                let d = &w.publication_topic_data;
                let guid = w.writer_proxy.remote_writer_guid;
                if prefix(guid) != own && &d.topic_name == topic && &d.type_name == typ {
                    now[i].push(WriterId::from(guid));
                }
            }
            now[i].sort_unstable();
            now[i].dedup();
            shared.counts[i].store(u32::try_from(now[i].len()).unwrap_or(u32::MAX), Ordering::Relaxed);
        }
        if let Ok(mut ever) = shared.ever.lock() {
            for (e, n) in ever.iter_mut().zip(&now) {
                for w in n {
                    if !e.contains(w) {
                        e.push(*w);
                    }
                }
            }
        }
        if let Ok(mut w) = shared.writers.lock() {
            *w = now;
        }
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_writer_id_prints_as_ros_prints_a_gid() {
        let mut b = [0u8; 16];
        b[0] = 0x01;
        b[1] = 0x0f;
        b[15] = 0xab;
        assert_eq!(WriterId(b).to_string(), "01.0f.00.00.00.00.00.00.00.00.00.00.00.00.00.ab");
    }
}
