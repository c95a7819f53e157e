//! The exit codes of `companion`, and the table `--help` prints.
//!
//! [`EXIT_CODES`] is the one list: `--help` renders it ([`help`]), and
//! `runtime/tests/protocol_doc.rs` compares it with the table of `docs/book/src/bridge.md` §6 (it
//! includes this file by path, so nothing here may depend on the rest of the crate).

/// Exit code: a bad flag, config file or other error (nothing of the run is written).
pub const EXIT_ERROR: u8 = 2;
/// Exit code: the peer process died or vanished during the run.
pub const EXIT_PEER_LOST: u8 = 3;
/// Exit code: the peer process is alive but stopped answering for `--peer-timeout`.
pub const EXIT_PEER_HUNG: u8 = 4;
/// Exit code: a demo with the same `--name` is running.
pub const EXIT_NAME_IN_USE: u8 = 5;
/// Exit code: the run completed, but the law rejected more than `--max-rejected` of its
/// steps (the robot got the safe zero command for them).
pub const EXIT_REJECTED: u8 = 6;
/// Exit code: the run completed, but real time was not kept: the robot was stopped, or more
/// than `--max-miss-fraction` of the deadlines were missed.
pub const EXIT_DEADLINES: u8 = 7;
/// Exit code: a `--chaos` run whose observed counts do not match what was injected, or whose
/// files are incomplete.
pub const EXIT_CHAOS_MISMATCH: u8 = 8;
/// Exit code: `explore` refused to start because another process is running on its `--out`
/// folder (it holds the folder's lock).
pub const EXIT_FOLDER_BUSY: u8 = 9;
/// Exit code: `ros2`: a second writer published on one of the node's inputs (the robot got the
/// zero command while it did; none of its samples was used).
pub const EXIT_SECOND_WRITER: u8 = 10;
/// Exit code: a panic (Rust's own code for it).
pub const EXIT_PANIC: u8 = 101;
/// Exit code: ended early by SIGINT or SIGTERM (files are written).
pub const EXIT_INTERRUPTED: u8 = 130;

/// One exit code as `--help` and `docs/book/src/bridge.md` list it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExitCodeDoc {
    /// The code.
    pub code: u8,
    /// The commands that exit with it; empty: every command.
    pub commands: &'static [&'static str],
    /// What it means (one line; `--help` wraps it).
    pub meaning: &'static str,
    /// A phrase of `meaning` that the row of `docs/book/src/bridge.md` §6 must contain too (so that
    /// the document cannot give the code another meaning).
    pub key: &'static str,
}

/// The commands of the HIL demo.
const HIL_ROLES: &[&str] = &["hil", "plant", "control"];

/// The commands that keep real time: the HIL demo's and the ROS 2 node.
const REAL_TIME: &[&str] = &["hil", "plant", "control", "ros2"];

/// Every exit code of `companion`, in increasing order.
pub const EXIT_CODES: &[ExitCodeDoc] = &[
    ExitCodeDoc { code: 0, commands: &[], meaning: "success", key: "success" },
    ExitCodeDoc {
        code: EXIT_ERROR,
        commands: &[],
        meaning: "bad flag value, config file or other error (nothing of the run is written); hil, plant and \
                  control also: a refused handshake, a peer of another protocol version, incompatible service \
                  types, no peer within --startup-timeout",
        key: "error",
    },
    ExitCodeDoc {
        code: EXIT_PEER_LOST,
        commands: HIL_ROLES,
        meaning: "the peer process died or left during the run",
        key: "died or left",
    },
    ExitCodeDoc {
        code: EXIT_PEER_HUNG,
        commands: HIL_ROLES,
        meaning: "the peer process is alive but silent for --peer-timeout",
        key: "--peer-timeout",
    },
    ExitCodeDoc {
        code: EXIT_NAME_IN_USE,
        commands: HIL_ROLES,
        meaning: "a demo with the same --name is running",
        key: "--name",
    },
    ExitCodeDoc {
        code: EXIT_REJECTED,
        commands: &["sim", "hil", "plant", "control", "ros2"],
        meaning: "the run completed, but the law rejected more than --max-rejected of its steps",
        key: "--max-rejected",
    },
    ExitCodeDoc {
        code: EXIT_DEADLINES,
        commands: REAL_TIME,
        meaning: "the run completed, but real time was not kept: the plant stopped the robot, or (hil and plant \
                  only) more than --max-miss-fraction of the deadlines were missed, or (ros2) more than \
                  --max-miss-fraction of its periods were zero commands for a stale, silent or bad input or late; \
                  when 6 applies too, hil, plant and ros2 exit 6, control exits 7",
        key: "stopped the robot",
    },
    ExitCodeDoc {
        code: EXIT_CHAOS_MISMATCH,
        commands: &["hil"],
        meaning: "--chaos: the counts observed do not match what was injected, or files are missing",
        key: "--chaos",
    },
    ExitCodeDoc {
        code: EXIT_FOLDER_BUSY,
        commands: &["explore"],
        meaning: "not started: another process is running in the same --out folder (it holds the folder's lock)",
        key: "--out folder",
    },
    ExitCodeDoc {
        code: EXIT_SECOND_WRITER,
        commands: &["ros2"],
        meaning: "a second writer published on an input of the node: the robot got the zero command while it \
                  did and none of its samples was used; summary.json names it (before 6 and 7)",
        key: "second writer",
    },
    ExitCodeDoc { code: EXIT_PANIC, commands: &[], meaning: "a panic: a bug, please report it", key: "panic" },
    ExitCodeDoc {
        code: EXIT_INTERRUPTED,
        commands: &["sim", "hil", "plant", "control", "explore", "ros2"],
        meaning: "interrupted by SIGINT or SIGTERM; the run's files are written",
        key: "SIGINT",
    },
];

/// The width `--help` wraps the table's meanings at (columns, indentation included).
const WIDTH: usize = 100;

/// The table of exit codes, as `--help` shows it (and docs/book/src/hil.md repeats it): one entry per
/// code, the commands it applies to in parentheses unless all do, wrapped at 100 columns.
pub fn help() -> String {
    let mut out = String::from("Exit codes:");
    for e in EXIT_CODES {
        let mut text = e.meaning.to_string();
        if !e.commands.is_empty() {
            text.push_str(&format!(" ({})", e.commands.join(", ")));
        }
        let mut line = format!("\n{:>5}   ", e.code);
        let mut len = line.len() - 1;
        for word in text.split(' ') {
            if len + 1 + word.len() > WIDTH && len > 9 {
                line.push_str("\n        ");
                len = 8;
            }
            line.push(' ');
            line.push_str(word);
            len += 1 + word.len();
        }
        out.push_str(&line);
    }
    out
}
