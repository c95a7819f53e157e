//! What Zenoh tells only its log about refused connections, handed to the plant's and the
//! controller's messages (cargo feature `zenoh`).
//!
//! A TLS handshake that fails — a peer without a certificate, with one of another CA, an
//! expired one, a plaintext peer on the TLS port — never reaches the application: zenoh's TLS
//! listener logs it (`tracing`, level WARN, target `zenoh_link_tls::…`) and goes on accepting.
//! The connecting side's failed attempts (its peer's certificate refused, nothing listening)
//! are logged at DEBUG by zenoh's orchestrator and retried. A [`tracing_subscriber`] layer
//! installed by [`install`] keeps those events, and only those, so that the endpoint can say
//! why nobody joined ([`take_refused`], [`last_connect_error`]). No other event is enabled:
//! the hot path's log calls stay disabled callsites — unless `COMPANION_ZENOH_LOG` names a
//! level (`error`, `warn`, `info`, `debug`, `trace`): then every event of zenoh's crates at
//! that level or above is also printed to stderr, with the time since the process started,
//! to see what zenoh itself did (e.g. why a link closed).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, Once, PoisonError};

use tracing::field::{Field, Visit};
use tracing::subscriber::Interest;
use tracing::{Event, Level, Metadata, Subscriber};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};

/// Refusals kept for [`take_refused`] (older ones are only counted).
const KEEP: usize = 16;

static REFUSED: AtomicU64 = AtomicU64::new(0);
static PENDING: Mutex<VecDeque<String>> = Mutex::new(VecDeque::new());
static LAST_CONNECT_ERROR: Mutex<Option<String>> = Mutex::new(None);

/// The listener's refusals: zenoh's TLS link and its QUIC acceptor at WARN.
fn is_refusal(m: &Metadata<'_>) -> bool {
    (m.target().starts_with("zenoh_link_tls") || m.target().starts_with("zenoh_link_commons::quic"))
        && *m.level() <= Level::WARN
}

/// The reason in a refusal's text: QUIC's close reason (`reason: b"…"`) if there is one, else
/// the text without zenoh's appended hint and source location.
fn refusal_reason(text: &str) -> Option<String> {
    if text.contains("QUIC") && !text.contains("acceptor failed") {
        return None;
    }
    if let Some((_, r)) = text.split_once("reason: b\"") {
        return Some(r.split('"').next().unwrap_or_default().to_string());
    }
    let t = text.split(". Hint:").next().unwrap_or_default();
    Some(t.split(" at /").next().unwrap_or_default().to_string())
}

/// The connector's failed attempts: zenoh's orchestrator at DEBUG or above.
fn is_connect_attempt(m: &Metadata<'_>) -> bool {
    m.target().starts_with("zenoh::net::runtime::orchestrator") && *m.level() <= Level::DEBUG
}

/// The level `COMPANION_ZENOH_LOG` asks to print (read once), if any.
fn echo_level() -> Option<Level> {
    static LEVEL: std::sync::OnceLock<Option<Level>> = std::sync::OnceLock::new();
    *LEVEL.get_or_init(|| std::env::var("COMPANION_ZENOH_LOG").ok().and_then(|v| v.trim().parse().ok()))
}

/// An event of zenoh's own crates at or above the echoed level.
fn is_echoed(m: &Metadata<'_>) -> bool {
    echo_level().is_some_and(|l| *m.level() <= l) && m.target().starts_with("zenoh")
}

#[derive(Debug)]
struct Keep;

struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.0, "{value:?}");
        }
    }
}

impl<S: Subscriber> Layer<S> for Keep {
    fn register_callsite(&self, m: &'static Metadata<'static>) -> Interest {
        if is_refusal(m) || is_connect_attempt(m) || is_echoed(m) {
            Interest::always()
        } else {
            Interest::never()
        }
    }

    fn enabled(&self, m: &Metadata<'_>, _: Context<'_, S>) -> bool {
        is_refusal(m) || is_connect_attempt(m) || is_echoed(m)
    }

    fn on_event(&self, event: &Event<'_>, _: Context<'_, S>) {
        let mut msg = Message(String::new());
        event.record(&mut msg);
        let m = event.metadata();
        if is_echoed(m) {
            static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
            let t = START.get_or_init(std::time::Instant::now).elapsed().as_secs_f64();
            eprintln!("zenoh {t:10.6} {} {}: {}", m.level(), m.target(), msg.0);
        }
        if is_refusal(m) {
            // zenoh's TLS accept loop appends a hint about file limits to every accept error.
            let Some(text) = refusal_reason(&msg.0) else { return };
            REFUSED.fetch_add(1, Ordering::Relaxed);
            let mut q = PENDING.lock().unwrap_or_else(PoisonError::into_inner);
            if q.len() == KEEP {
                q.pop_front();
            }
            q.push_back(text);
        } else if msg.0.contains("Unable to connect") {
            *LAST_CONNECT_ERROR.lock().unwrap_or_else(PoisonError::into_inner) = Some(msg.0);
        }
    }
}

/// Installs the layer as the process's global subscriber (once; a no-op if another global
/// subscriber was installed first).
pub fn install() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = tracing::subscriber::set_global_default(tracing_subscriber::registry().with(Keep));
    });
}

/// Connections refused by the TLS listener so far (all of them, kept or not).
pub fn refused() -> u64 {
    REFUSED.load(Ordering::Relaxed)
}

/// The refusals not yet taken (at most the last 16), oldest first.
pub fn take_refused() -> Vec<String> {
    PENDING.lock().unwrap_or_else(PoisonError::into_inner).drain(..).collect()
}

/// The connector's last failed attempt (zenoh's words), if any.
pub fn last_connect_error() -> Option<String> {
    LAST_CONNECT_ERROR.lock().unwrap_or_else(PoisonError::into_inner).clone()
}

#[cfg(test)]
mod tests {
    use super::refusal_reason;

    #[test]
    fn a_refusal_is_reduced_to_its_reason() {
        let quic = "QUIC acceptor failed: ConnectionClosed(ConnectionClose { error_code: Code::crypto(30), \
                    frame_type: None, reason: b\"invalid peer certificate: UnknownIssuer\" }) at /root/x.rs:9.";
        assert_eq!(refusal_reason(quic).as_deref(), Some("invalid peer certificate: UnknownIssuer"));
        let tls =
            "received corrupt message of type InvalidContentType. Hint: increase the system open file limit.";
        assert_eq!(
            refusal_reason(tls).as_deref(),
            Some("received corrupt message of type InvalidContentType")
        );
        assert_eq!(refusal_reason("QUIC endpoint rebinding at /x.rs:1"), None);
    }
}
