//! A Zenoh round trip split at each hop, on one clock.
//!
//! Both processes of the ping-pong run on one machine, so one `CLOCK_MONOTONIC` times every
//! step of a round trip in either process. Each round trip is stamped at the benchmark's
//! `put` call and its return, the peer's subscriber callback (the first thing Zenoh's thread
//! does with the message: `zenoh_link::ZenohEndpoint::try_receive_stamped`),
//! the peer's loop waking with it, the peer's `put` call and return, the benchmark's callback
//! and the benchmark's loop waking. [`HOPS`] are the differences; they add up to the round
//! trip, which is timed independently as well (the ping-pong's own sample, from the
//! message's timestamp, checked by the second clock: [`super::pingpong::SecondClock`]).
//!
//! The peer's `put` return is known only after the echo left, so each echo carries the
//! previous echo's `put` duration and the return hop of round trip *i* is split when echo
//! *i + 1* comes.
//!
//! The receiver may have the message before the sender's `put` returns (with the low-latency
//! transport `put` writes the socket itself, and a receiver on the other CPU reads it at
//! once): a `put` hop then ends at the receiver's callback and the next hop is 0, so that the
//! hops still add up; such round trips are counted
//! ([`HopReport::delivered_before_put_returned`]).

use serde::Serialize;

use crate::domain::histogram::{LatencyHistogram, Percentiles};

/// The hops of one round trip, in order.
pub const HOPS: [&str; 7] = [
    "bench put (call → return or delivery)",
    "bench → peer in zenoh (put return → peer callback)",
    "peer hand-off (callback → loop awake)",
    "peer turnaround (awake → put call)",
    "peer put (call → return or delivery)",
    "peer → bench in zenoh (put return → bench callback)",
    "bench hand-off (callback → loop awake)",
];

/// The sum of the hops' medians may differ from the round trip's median by this share (the
/// median of a sum is not the sum of medians; their means are exact).
pub const MEDIAN_TOLERANCE: f64 = 0.15;
/// The sum of the hops' means may differ from the round trip's mean by this share (the
/// return `put` of one round trip is the previous echo's).
pub const MEAN_TOLERANCE: f64 = 0.02;
/// The hops' round trip (first `put` call → loop awake with the answer) may differ from the
/// ping-pong's own sample (the message's timestamp → after the answer is taken) by this share
/// at the median.
pub const SAMPLE_TOLERANCE: f64 = 0.05;

/// One hop's figures.
#[derive(Clone, Debug, Serialize)]
pub struct HopRow {
    /// [`HOPS`]' name, or `round trip`.
    pub name: String,
    /// Its percentiles (ns).
    pub ns: Percentiles,
    /// Its mean (ns).
    pub mean_ns: f64,
}

/// The hops of one configuration's round trips, and their checks.
#[derive(Clone, Debug, Serialize)]
pub struct HopReport {
    /// The configuration (link, Zenoh settings, hand-off).
    pub config: String,
    /// The hops, then the round trip they add up to.
    pub rows: Vec<HopRow>,
    /// The round trip by the ping-pong's own sample (independent of the hops' stamps).
    pub sample: Percentiles,
    /// Stamps out of order (a hop that would be negative: recorded as 0).
    pub out_of_order: u64,
    /// Hops whose receiver had the message before the sender's `put` returned.
    pub delivered_before_put_returned: u64,
}

impl HopReport {
    /// The round trip's row.
    pub fn total(&self) -> &HopRow {
        &self.rows[self.rows.len() - 1]
    }

    fn hops(&self) -> &[HopRow] {
        &self.rows[..self.rows.len() - 1]
    }

    /// The sum of the hops' medians over the round trip's median.
    pub fn median_share(&self) -> f64 {
        let sum: u64 = self.hops().iter().map(|h| h.ns.p50).sum();
        sum as f64 / self.total().ns.p50.max(1) as f64
    }

    /// The sum of the hops' means over the round trip's mean.
    pub fn mean_share(&self) -> f64 {
        let sum: f64 = self.hops().iter().map(|h| h.mean_ns).sum();
        sum / self.total().mean_ns.max(1.0)
    }

    /// The hops' round trip's median over the ping-pong's own sample's median.
    pub fn sample_share(&self) -> f64 {
        self.total().ns.p50 as f64 / self.sample.p50.max(1) as f64
    }

    /// Whether the instrument checks out: no stamp out of order, and the three shares within
    /// their tolerances ([`MEDIAN_TOLERANCE`], [`MEAN_TOLERANCE`], [`SAMPLE_TOLERANCE`]).
    pub fn agrees(&self) -> bool {
        let within = |x: f64, tol: f64| (x - 1.0).abs() <= tol;
        self.out_of_order == 0
            && self.total().ns.count > 0
            && within(self.median_share(), MEDIAN_TOLERANCE)
            && within(self.mean_share(), MEAN_TOLERANCE)
            && within(self.sample_share(), SAMPLE_TOLERANCE)
    }
}

/// The stamps of one round trip (`CLOCK_MONOTONIC`, ns).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stamps {
    /// The benchmark calls `put`.
    pub put_call: u64,
    /// Its `put` returns.
    pub put_return: u64,
    /// The peer's callback has the message.
    pub peer_callback: u64,
    /// The peer's loop has it.
    pub peer_awake: u64,
    /// The peer calls `put` with the echo.
    pub peer_put_call: u64,
    /// The previous echo's `put` took this long (ns).
    pub previous_peer_put_ns: u64,
    /// The benchmark's callback has the echo.
    pub callback: u64,
    /// The benchmark's loop has it.
    pub awake: u64,
}

/// Collects [`Stamps`] into per-hop histograms.
#[derive(Debug)]
pub struct HopRecorder {
    hops: [LatencyHistogram; 7],
    sums: [u128; 7],
    counts: [u64; 7],
    total: LatencyHistogram,
    total_sum: u128,
    out_of_order: u64,
    overlapped: u64,
    /// The previous round trip's peer put call → bench callback, split when the next echo
    /// brings that put's duration.
    pending_return: Option<u64>,
}

impl Default for HopRecorder {
    fn default() -> Self {
        Self {
            hops: std::array::from_fn(|_| LatencyHistogram::new()),
            sums: [0; 7],
            counts: [0; 7],
            total: LatencyHistogram::new(),
            total_sum: 0,
            out_of_order: 0,
            overlapped: 0,
            pending_return: None,
        }
    }
}

impl HopRecorder {
    fn diff(&mut self, later: u64, earlier: u64) -> u64 {
        if later < earlier {
            self.out_of_order += 1;
        }
        later.saturating_sub(earlier)
    }

    /// A `put` from `call` that returned after `put_ns` and whose message the receiver had
    /// `delivered_ns` after the call: the `put` hop and the transit hop after it.
    fn split(&mut self, put_ns: u64, delivered_ns: u64) -> (u64, u64) {
        if put_ns > delivered_ns {
            self.overlapped += 1;
        }
        let put = put_ns.min(delivered_ns);
        (put, delivered_ns - put)
    }

    fn put(&mut self, hop: usize, ns: u64) {
        self.hops[hop].record(ns);
        self.sums[hop] += u128::from(ns);
        self.counts[hop] += 1;
    }

    /// One round trip's stamps; `record`: after the warm-up (a round trip before it only
    /// leaves its return hop pending).
    pub fn record(&mut self, s: &Stamps, record: bool) {
        let put_ns = self.diff(s.put_return, s.put_call);
        let delivered_ns = self.diff(s.peer_callback, s.put_call);
        let (put, transit) = self.split(put_ns, delivered_ns);
        let hops = [
            put,
            transit,
            self.diff(s.peer_awake, s.peer_callback),
            self.diff(s.peer_put_call, s.peer_awake),
        ];
        let back = self.diff(s.callback, s.peer_put_call);
        let handoff = self.diff(s.awake, s.callback);
        let total = self.diff(s.awake, s.put_call);
        if let Some(prev) = self.pending_return.take() {
            if record {
                let (put, transit) = self.split(s.previous_peer_put_ns, prev);
                self.put(4, put);
                self.put(5, transit);
            }
        }
        if !record {
            self.out_of_order = 0;
            self.overlapped = 0;
            self.pending_return = Some(back);
            return;
        }
        for (i, h) in hops.into_iter().enumerate() {
            self.put(i, h);
        }
        self.put(6, handoff);
        self.total.record(total);
        self.total_sum += u128::from(total);
        self.pending_return = Some(back);
    }

    /// The report of configuration `config`, beside the ping-pong's own samples.
    pub fn finish(self, config: String, sample: &LatencyHistogram) -> HopReport {
        let mean = |sum: u128, n: u64| if n == 0 { 0.0 } else { sum as f64 / n as f64 };
        let mut rows: Vec<HopRow> = HOPS
            .iter()
            .enumerate()
            .map(|(i, name)| HopRow {
                name: (*name).to_string(),
                ns: self.hops[i].percentiles(),
                mean_ns: mean(self.sums[i], self.counts[i]),
            })
            .collect();
        rows.push(HopRow {
            name: "round trip (put call → loop awake)".into(),
            ns: self.total.percentiles(),
            mean_ns: mean(self.total_sum, self.total.percentiles().count),
        });
        HopReport {
            config,
            rows,
            sample: sample.percentiles(),
            out_of_order: self.out_of_order,
            delivered_before_put_returned: self.overlapped,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamps(base: u64, prev_put: u64) -> Stamps {
        Stamps {
            put_call: base,
            put_return: base + 2_000,
            peer_callback: base + 30_000,
            peer_awake: base + 35_000,
            peer_put_call: base + 36_000,
            previous_peer_put_ns: prev_put,
            callback: base + 70_000,
            awake: base + 75_000,
        }
    }

    /// The hops of stamps made up so that each is known add up to the round trip, the return
    /// put is split with the next echo's figure, and the checks pass; a stamp out of order is
    /// counted and fails them.
    #[test]
    fn the_hops_add_up_to_the_round_trip() {
        let mut r = HopRecorder::default();
        let mut sample = LatencyHistogram::new();
        r.record(&stamps(0, 0), false);
        for i in 1..=100 {
            r.record(&stamps(i * 1_000_000, 3_000), true);
            sample.record(75_000);
        }
        let rep = r.finish("test".into(), &sample);
        let p50: Vec<u64> = rep.rows.iter().map(|h| h.ns.p50).collect();
        // (The histogram keeps 3 significant digits.)
        let want = [2_000u64, 28_000, 5_000, 1_000, 3_000, 31_000, 5_000, 75_000];
        assert!(p50.iter().zip(want).all(|(g, w)| g.abs_diff(w) * 1_000 <= w), "{p50:?}");
        assert_eq!(rep.rows[4].ns.count, 100, "the warm-up's return hop is split by the first recorded echo");
        assert!((rep.median_share() - 1.0).abs() < 0.01, "{}", rep.median_share());
        assert!((rep.mean_share() - 1.0).abs() < 0.01, "{}", rep.mean_share());
        assert!(rep.agrees(), "{rep:?}");
        assert_eq!((rep.out_of_order, rep.delivered_before_put_returned), (0, 0));
        // The peer has the message 1 µs after the put call, before the put returned (2 µs):
        // the put hop ends there, the hops still add up, and it is counted, not an error.
        let mut r = HopRecorder::default();
        let mut early = stamps(1_000_000, 3_000);
        early.peer_callback = early.put_call + 1_000;
        r.record(&early, true);
        let rep = r.finish("early".into(), &sample);
        assert_eq!((rep.rows[0].ns.p50 / 10, rep.rows[1].ns.p50), (100, 0));
        assert_eq!((rep.out_of_order, rep.delivered_before_put_returned), (0, 1));
        // A callback before the put was even called is the clocks' fault: counted, and fails.
        let mut r = HopRecorder::default();
        let mut bad = stamps(1_000_000, 3_000);
        bad.peer_callback = bad.put_call - 1;
        r.record(&bad, true);
        let rep = r.finish("bad".into(), &sample);
        assert_eq!(rep.out_of_order, 1);
        assert!(!rep.agrees());
    }
}
