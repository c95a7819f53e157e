//! The exit codes of `companion`.

/// Exit code: a bad flag, config file or other error.
pub const EXIT_ERROR: u8 = 2;
/// Exit code: the peer process died or vanished during the run.
pub const EXIT_PEER_LOST: u8 = 3;
/// Exit code: the peer process is alive but stopped answering for `--peer-timeout`.
pub const EXIT_PEER_HUNG: u8 = 4;
/// Exit code: a demo with the same `--name` is running.
pub const EXIT_NAME_IN_USE: u8 = 5;
/// Exit code: ended early by SIGINT or SIGTERM (files are written).
pub const EXIT_INTERRUPTED: u8 = 130;
