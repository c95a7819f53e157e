//! How a HIL run ended, on each side (the command line maps these to exit codes).

use crate::transport::wire::Refusal;

/// Why the plant's run ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlantEnd {
    /// Every step ran.
    Completed,
    /// SIGINT/SIGTERM: the run ended early, cleanly.
    Interrupted {
        /// The last cycle.
        cycle: u64,
    },
    /// The controller's process died.
    ControllerDied {
        /// Its pid.
        pid: i32,
        /// The cycle at which it was found dead.
        cycle: u64,
        /// Silence before the finding (ns).
        silent_ns: u64,
        /// Found by its session's lease running out (Zenoh over QUIC): dead, or unreachable.
        expired: bool,
    },
    /// The controller's node is gone (it exited without waiting for the end of the run).
    ControllerGone {
        /// The cycle.
        cycle: u64,
    },
    /// The controller is alive but has not answered for `--peer-timeout`.
    ControllerHung {
        /// The cycle.
        cycle: u64,
        /// Silence (ns).
        silent_ns: u64,
        /// The controller's pid, as its transport reports it.
        pid: i32,
    },
    /// The controller refused to serve this plant (a mismatch it names).
    Refused(Refusal),
}

impl PlantEnd {
    /// One sentence.
    pub fn describe(&self) -> String {
        let ms = |ns: &u64| *ns as f64 / 1e6;
        match self {
            Self::Completed => "completed".into(),
            Self::Interrupted { cycle } => format!("interrupted at cycle {cycle}"),
            Self::ControllerDied { pid, cycle, silent_ns, expired: false } => format!(
                "controller process {pid} died: found dead at cycle {cycle}, {:.1} ms after its last command; \
                 robot stopped",
                ms(silent_ns)
            ),
            Self::ControllerDied { pid, cycle, silent_ns, expired: true } => format!(
                "controller process {pid} died or is unreachable: its session's lease ran out, found at cycle \
                 {cycle}, {:.1} ms after its last command; robot stopped",
                ms(silent_ns)
            ),
            Self::ControllerGone { cycle } => {
                format!("controller exited before the end of the run (noticed at cycle {cycle}); robot stopped")
            }
            Self::ControllerHung { cycle, silent_ns, .. } => format!(
                "controller alive but silent for {:.0} ms (at cycle {cycle}); robot stopped, run abandoned",
                ms(silent_ns)
            ),
            Self::Refused(why) => format!("the controller refused this plant: {why}"),
        }
    }
}

/// How the controller's run ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ControlEnd {
    /// The plant sent its last measurement and got its answer.
    EndOfRun,
    /// The plant's process died.
    PlantDied {
        /// Its pid.
        pid: i32,
        /// The last measurement answered.
        last_seq: Option<u64>,
        /// Time from the last measurement to the finding (ns).
        silent_ns: u64,
        /// Found by its session's lease running out (Zenoh over QUIC): dead, or unreachable.
        expired: bool,
    },
    /// The plant's node is gone.
    PlantGone {
        /// The last measurement answered.
        last_seq: Option<u64>,
    },
    /// The plant is alive but silent.
    PlantHung {
        /// Silence (ns).
        silent_ns: u64,
        /// The plant's pid, as its transport reports it.
        pid: i32,
    },
    /// SIGINT/SIGTERM and no end of run within a second.
    Interrupted,
}

fn ms(ns: u64) -> f64 {
    ns as f64 / 1e6
}

impl ControlEnd {
    /// One sentence.
    pub fn describe(&self) -> String {
        let end = self;
        let seq = |s: &Option<u64>| {
            s.map_or("before the first measurement".to_string(), |s| format!("after cycle {s}"))
        };
        match end {
            ControlEnd::EndOfRun => "end of run".into(),
            ControlEnd::PlantDied { pid, last_seq, silent_ns, expired: false } => format!(
                "the plant (pid {pid}) died {}; noticed {:.1} ms after its last measurement",
                seq(last_seq),
                ms(*silent_ns)
            ),
            ControlEnd::PlantDied { pid, last_seq, silent_ns, expired: true } => format!(
                "the plant (pid {pid}) died or is unreachable {}: its session's lease ran out, noticed {:.1} ms \
                 after its last measurement",
                seq(last_seq),
                ms(*silent_ns)
            ),
            ControlEnd::PlantGone { last_seq } => format!("the plant left {}", seq(last_seq)),
            ControlEnd::PlantHung { silent_ns, .. } => {
                format!("the plant is alive but has sent nothing for {:.0} ms", ms(*silent_ns))
            }
            ControlEnd::Interrupted => "interrupted".into(),
        }
    }
}
