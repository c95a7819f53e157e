//! The DDS round trip (a build with the `ros2` feature): the ping-pong of [`super::pingpong`]
//! with the same messages (the 344-byte measurement out, the 248-byte command back, each a CDR
//! array of octets) over RustDDS on loopback UDP, as `companion ros2` talks to a robot. Both
//! sides are ROS 2 nodes of ros2-client (reliable, keep last 10, volatile: ROS 2's default
//! profile) on topics `/companion_latency_<name>/ping` and `…/pong`, and both sleep in
//! `mio`'s poll until their subscription has a sample.
//!
//! Secured ([`Keystore`]), the same under SROS 2 as `companion ros2` runs with an enclave:
//! DDS-Security's builtin plugins (authentication by certificate, access control by signed
//! permissions, every sample encrypted and signed with AES-GCM), each side with its own
//! enclave of a keystore made for the run in the layout of `scripts/sros2-keystore` (SROS 2's
//! default governance, permissions for exactly the two topics).

use std::path::Path;
use std::time::Duration;

use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    Subscription,
};
use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::error::LatencyError;
use super::pingpong::{echo, ping, rt_cpus, spawn_peer, RtScope, Samples, SecondClock, Transport};
use crate::domain::histogram::LatencyHistogram;
use crate::domain::observe::Observer;
use crate::sys::lock::DemoName;
use crate::sys::rt;
use crate::transport::wire::{flags, CommandMsg, MeasurementMsg, COMMAND_SIZE, MEASUREMENT_SIZE};

/// `N` bytes as a CDR `octet[N]` (no length on the wire).
#[derive(Clone, Copy, Debug)]
struct Fixed<const N: usize>([u8; N]);

impl<const N: usize> Serialize for Fixed<N> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(N)?;
        for b in &self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

impl<'de, const N: usize> Deserialize<'de> for Fixed<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for V<N> {
            type Value = Fixed<N>;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{N} octets")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Fixed<N>, A::Error> {
                let mut b = [0u8; N];
                for (i, x) in b.iter_mut().enumerate() {
                    *x = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Fixed(b))
            }
        }
        d.deserialize_tuple(N, V::<N>)
    }
}

type Ping = Fixed<MEASUREMENT_SIZE>;
type Pong = Fixed<COMMAND_SIZE>;

fn failed(what: &str, e: impl std::fmt::Debug) -> LatencyError {
    LatencyError::Dds(format!("{what}: {e:?}"))
}

/// One side: its node, what it sends and what it reads, and a poll on the reader.
struct Side<O: Serialize, I: 'static> {
    tx: Publisher<O>,
    rx: Subscription<I>,
    poll: Poll,
    events: Events,
    _node: Node,
    _context: Context,
}

/// The DDS name of the latency nodes of `name`.
fn node_base(name: &DemoName) -> String {
    format!("companion_latency_{}", name.as_str().replace('-', "_"))
}

impl<O: Serialize, I: 'static + serde::de::DeserializeOwned> Side<O, I> {
    fn open(
        name: &DemoName,
        role: &str,
        tx: &str,
        rx: &str,
        keystore: Option<&Path>,
    ) -> Result<Self, LatencyError> {
        let mut options = ContextOptions::new();
        if let Some(ks) = keystore {
            options = options.enable_security(ks.join("enclaves").join(role), String::new());
        }
        let context = Context::with_options(options).map_err(|e| failed("joining DDS domain 0", e))?;
        let node_name = node_base(name);
        let mut node = context
            .new_node(
                NodeName::new("/", &format!("{node_name}_{role}")).map_err(|e| failed("node name", e))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(|e| failed("creating the node", e))?;
        let qos = QosProfile::publisher_default()
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 10 })
            .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)));
        let topic = |t: &str, ty: &str| {
            let n = Name::new("/", &format!("{node_name}_{t}")).map_err(|e| failed("topic name", e))?;
            node.create_topic(&n, MessageTypeName::new("companion", ty), &qos).map_err(|e| failed("topic", e))
        };
        let (tx_topic, rx_topic) = (topic(tx, tx)?, topic(rx, rx)?);
        let tx = node.create_publisher::<O>(&tx_topic, None).map_err(|e| failed("publisher", e))?;
        let mut rx = node.create_subscription::<I>(&rx_topic, None).map_err(|e| failed("subscription", e))?;
        let poll = Poll::new().map_err(|e| failed("poll", e))?;
        poll.registry().register(&mut rx, Token(1), Interest::READABLE).map_err(|e| failed("poll", e))?;
        Ok(Self { tx, rx, poll, events: Events::with_capacity(8), _node: node, _context: context })
    }

    /// The next sample, sleeping in the poll for it up to `timeout`.
    fn next(&mut self, timeout: Duration) -> Result<Option<I>, LatencyError> {
        let until = rt::monotonic_ns() + timeout.as_nanos() as u64;
        loop {
            if let Some((m, _)) = self.rx.take().map_err(|e| failed("take", e))? {
                return Ok(Some(m));
            }
            let now = rt::monotonic_ns();
            if now >= until {
                return Ok(None);
            }
            let left = Duration::from_nanos((until - now).min(100_000_000));
            self.poll.poll(&mut self.events, Some(left)).map_err(|e| failed("poll", e))?;
        }
    }
}

/// Round trips over DDS (module docs), `warmup` unrecorded first, back to back.
///
/// # Errors
/// The peer could not be started, never answered, or stopped answering.
pub fn round_trips(
    exe: &Path,
    iterations: u64,
    warmup: u64,
    use_rt: bool,
    secure: bool,
    observer: &dyn Observer,
) -> Result<(LatencyHistogram, SecondClock), LatencyError> {
    let tag = if secure { "sros2" } else { "dds" };
    let name = DemoName::new(&format!("latency-{}-{tag}", std::process::id()))?;
    let (own_cpu, peer_cpu) = rt_cpus();
    let mut args =
        vec!["--transport".into(), Transport::Dds.as_str().into(), "--name".into(), name.to_string()];
    if use_rt {
        args.extend(["--rt-cpu".to_string(), peer_cpu.to_string()]);
    }
    let keystore = if secure { Some(Keystore::make(&name)?) } else { None };
    if let Some(k) = &keystore {
        args.extend(["--tls-dir".to_string(), k.root.display().to_string()]);
    }
    let ks = keystore.as_ref().map(|k| k.root.as_path());
    let mut side = Side::<Ping, Pong>::open(&name, "bench", "ping", "pong", ks)?;
    let mut child = spawn_peer(exe, &args)?;
    // Discovery: ping with sequence number u64::MAX until the peer answers one.
    let start = rt::monotonic_ns();
    'matched: loop {
        let hello = ping(u64::MAX, false);
        side.tx.publish(Fixed(hello.to_bytes())).map_err(|e| failed("publish", e))?;
        while let Some(p) = side.next(Duration::from_millis(50))? {
            if CommandMsg::from_bytes(&p.0).seq == u64::MAX {
                break 'matched;
            }
        }
        if rt::monotonic_ns() - start > 20_000_000_000 {
            return Err(LatencyError::PeerStopped { transport: "dds", iteration: 0 });
        }
    }
    let _rt = use_rt.then(|| RtScope::enter(own_cpu, observer));
    let mut samples = Samples::new(warmup);
    let total = warmup + iterations;
    for i in 0..total {
        samples.begin(i);
        let msg = ping(i, i + 1 == total);
        let t0 = msg.plant_time_ns;
        side.tx.publish(Fixed(msg.to_bytes())).map_err(|e| failed("publish", e))?;
        loop {
            match side.next(Duration::from_secs(5))? {
                Some(p) if CommandMsg::from_bytes(&p.0).seq == i => break,
                Some(_) => {}
                None => return Err(LatencyError::PeerStopped { transport: "dds", iteration: i }),
            }
        }
        samples.record(i, rt::monotonic_ns() - t0);
    }
    drop(_rt);
    child.finish(Duration::from_secs(5))?;
    Ok(samples.finish())
}

/// The echoing side: answers every measurement with a command until `END_OF_RUN`; secured
/// with enclave `peer` of `keystore` when given.
///
/// # Errors
/// The transport failed or the benchmark went silent for 10 s.
pub fn peer(name: &DemoName, keystore: Option<&Path>) -> Result<(), LatencyError> {
    let mut side = Side::<Pong, Ping>::open(name, "peer", "pong", "ping", keystore)?;
    loop {
        let Some(p) = side.next(Duration::from_secs(10))? else { return Err(LatencyError::BenchmarkGone) };
        let m = MeasurementMsg::from_bytes(&p.0);
        side.tx.publish(Fixed(echo(&m, rt::monotonic_ns()).to_bytes())).map_err(|e| failed("publish", e))?;
        if m.has(flags::END_OF_RUN) {
            // Let the last answer leave before the participant goes.
            std::thread::sleep(Duration::from_millis(200));
            return Ok(());
        }
    }
}

/// An SROS 2 keystore made for one secured run (removed after it): one CA (identity and
/// permissions), SROS 2's default governance for domain 0, enclaves `bench` and `peer` granted
/// the two topics (and what ros2-client makes for every node), keys on prime256v1, documents
/// signed S/MIME — the layout and contents of `scripts/sros2-keystore`, through the OpenSSL
/// library RustDDS's plugins link.
#[derive(Debug)]
pub struct Keystore {
    root: std::path::PathBuf,
}

impl Drop for Keystore {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

/// SROS 2's default governance (sros2's `policy/defaults/dds/governance.xml`) for domain 0.
const GOVERNANCE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id>0</id></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"#;

impl Keystore {
    /// Makes it in the temporary folder.
    ///
    /// # Errors
    /// OpenSSL or the file system failed.
    pub fn make(name: &DemoName) -> Result<Self, LatencyError> {
        use openssl::asn1::Asn1Time;
        use openssl::bn::BigNum;
        use openssl::ec::{EcGroup, EcKey};
        use openssl::hash::MessageDigest;
        use openssl::nid::Nid;
        use openssl::pkcs7::{Pkcs7, Pkcs7Flags};
        use openssl::pkey::{PKey, Private};
        use openssl::stack::Stack;
        use openssl::x509::extension::BasicConstraints;
        use openssl::x509::{X509Name, X509};

        let ssl = |e: openssl::error::ErrorStack| failed("making the SROS 2 keystore", e);
        let io = |e: std::io::Error| failed("writing the SROS 2 keystore", e);
        let key = || -> Result<PKey<Private>, openssl::error::ErrorStack> {
            let group = EcGroup::from_curve_name(Nid::X9_62_PRIME256V1)?;
            PKey::from_ec_key(EcKey::generate(&group)?)
        };
        let cert = |cn: &str,
                    key: &PKey<Private>,
                    issuer: Option<(&X509, &PKey<Private>)>|
         -> Result<X509, openssl::error::ErrorStack> {
            let mut n = X509Name::builder()?;
            n.append_entry_by_nid(Nid::COMMONNAME, cn)?;
            let subject = n.build();
            let mut b = X509::builder()?;
            b.set_version(2)?;
            let serial = BigNum::from_u32(rand::random::<u32>() >> 1)?.to_asn1_integer()?;
            b.set_serial_number(&serial)?;
            b.set_subject_name(&subject)?;
            b.set_issuer_name(issuer.map_or(&subject, |(c, _)| c.subject_name()))?;
            b.set_pubkey(key)?;
            let (start, end) = (Asn1Time::days_from_now(0)?, Asn1Time::days_from_now(2)?);
            b.set_not_before(&start)?;
            b.set_not_after(&end)?;
            let ca = issuer.is_none();
            let bc = if ca {
                BasicConstraints::new().critical().ca().pathlen(1).build()?
            } else {
                BasicConstraints::new().build()?
            };
            b.append_extension(bc)?;
            b.sign(issuer.map_or(key, |(_, k)| k), MessageDigest::sha256())?;
            Ok(b.build())
        };
        let root = std::env::temp_dir().join(format!("companion-{name}-keystore"));
        let _ = std::fs::remove_dir_all(&root);
        let ks = Self { root };
        let ca_key = key().map_err(ssl)?;
        let ca = cert("sros2CA", &ca_key, None).map_err(ssl)?;
        let smime = |text: &str| -> Result<Vec<u8>, openssl::error::ErrorStack> {
            let flags = Pkcs7Flags::DETACHED | Pkcs7Flags::TEXT;
            let none: Stack<X509> = Stack::new()?;
            Pkcs7::sign(&ca, &ca_key, &none, text.as_bytes(), flags)?.to_smime(text.as_bytes(), flags)
        };
        let governance = smime(GOVERNANCE).map_err(ssl)?;
        let base = node_base(name);
        let topics = [
            format!("rt/{base}_ping"),
            format!("rt/{base}_pong"),
            "rt/rosout".into(),
            "rt/parameter_events".into(),
            "ros_discovery_info".into(),
        ];
        let list: String = topics.iter().map(|t| format!("<topic>{t}</topic>")).collect();
        for role in ["bench", "peer"] {
            let dir = ks.root.join("enclaves").join(role);
            std::fs::create_dir_all(&dir).map_err(io)?;
            let k = key().map_err(ssl)?;
            let c = cert(&format!("/{role}"), &k, Some((&ca, &ca_key))).map_err(ssl)?;
            let permissions = format!(
                r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="/{role}">
      <subject_name>CN=/{role}</subject_name>
      <validity><not_before>2000-01-01T00:00:00</not_before><not_after>2100-01-01T00:00:00</not_after></validity>
      <allow_rule>
        <domains><id>0</id></domains>
        <publish><topics>{list}</topics></publish>
        <subscribe><topics>{list}</topics></subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"#
            );
            let ca_pem = ca.to_pem().map_err(ssl)?;
            for (file, bytes) in [
                ("identity_ca.cert.pem", ca_pem.clone()),
                ("permissions_ca.cert.pem", ca_pem),
                ("cert.pem", c.to_pem().map_err(ssl)?),
                ("key.pem", k.private_key_to_pem_pkcs8().map_err(ssl)?),
                ("governance.p7s", governance.clone()),
                ("permissions.p7s", smime(&permissions).map_err(ssl)?),
            ] {
                std::fs::write(dir.join(file), bytes).map_err(io)?;
            }
        }
        Ok(ks)
    }
}
