//! The exit codes of `companion`, and the table `--help` prints.

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
/// Exit code: ended early by SIGINT or SIGTERM (files are written).
pub const EXIT_INTERRUPTED: u8 = 130;

/// The table of exit codes, as `--help` shows it (and the README repeats it).
pub const EXIT_CODES_HELP: &str = "\
Exit codes:
    0    success
    2    bad flag value, config file or other error (nothing of the run is written)
    3    the peer process died or left during the run (hil, plant, control)
    4    the peer process is alive but silent for --peer-timeout (hil, plant, control)
    5    a demo with the same --name is running (hil, plant, control)
    6    the run completed, but the law rejected more than --max-rejected of its steps
    7    the run completed, but real time was not kept: the robot was stopped, or more than
         --max-miss-fraction of the deadlines were missed (hil, plant)
    8    --chaos: the counts observed do not match what was injected, or files are missing
  101    a panic: a bug, please report it
  130    interrupted by SIGINT or SIGTERM (the run's files are written)";
