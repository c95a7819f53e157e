//! The one recording thread: a [`RowSink`] (a [`Recorder`](super::Recorder) or a
//! [`Log`](super::recorder::Log)) on a thread of its own, fed with rows through a lock-free
//! single-producer ring allocated once (`rtrb`), flushing `timeseries.csv` at a fixed
//! interval.
//!
//! The HIL plant's real-time loop pushes every row without ever waiting
//! ([`RecordWriter::try_push`]: a full ring drops the row, and the caller counts it), and the
//! thread accumulates the summary too; the in-process simulation keeps the summary itself
//! and pushes only the logged rows, waiting for room if it must ([`RecordWriter`] as a
//! [`RowSink`]), so that formatting the CSV runs in parallel with the simulation and no row
//! is lost. Either way the bytes written are those of the same sink on the calling thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use std::marker::PhantomData;

use companion_core::Planar;

use super::error::RecordError;
use super::recorder::RowSink;
use super::row::{Row, Task};
use crate::domain::controller::JOINTS;

/// One row on its way to the writer thread.
#[derive(Clone, Copy, Debug)]
pub struct LogItem<S: Task = Planar, const N: usize = JOINTS> {
    /// The step.
    pub n: u64,
    /// Its row.
    pub row: Row<S, N>,
    /// Whether it is the last step.
    pub last: bool,
}

/// How long the writer thread sleeps when the ring is empty.
const IDLE: Duration = Duration::from_millis(2);
/// How long a waiting producer sleeps when the ring is full.
const BACKOFF: Duration = Duration::from_micros(50);

/// A [`RowSink`] `K` of rows of an arm of `N` joints (targets in `S`) running on its own
/// thread.
#[derive(Debug)]
pub struct RecordWriter<K, S: Task = Planar, const N: usize = JOINTS> {
    tx: rtrb::Producer<LogItem<S, N>>,
    done: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<K, RecordError>>>,
    log_every: u64,
    space: PhantomData<S>,
}

impl<K: RowSink<S, N> + Send + 'static, S: Task, const N: usize> RecordWriter<K, S, N> {
    /// Starts the thread with a ring of `capacity` rows; it flushes the file every
    /// `flush_every` (and at the end).
    ///
    /// # Errors
    /// The thread cannot be started.
    pub fn spawn(mut recorder: K, capacity: usize, flush_every: Duration) -> Result<Self, RecordError> {
        let (tx, mut rx) = rtrb::RingBuffer::<LogItem<S, N>>::new(capacity);
        let done = Arc::new(AtomicBool::new(false));
        let finish = Arc::clone(&done);
        let log_every = recorder.log_every();
        let thread = std::thread::Builder::new()
            .name("csv-writer".into())
            .spawn(move || {
                let mut last_flush = Instant::now();
                loop {
                    let finishing = finish.load(Ordering::Acquire);
                    let mut got = false;
                    while let Ok(item) = rx.pop() {
                        recorder.record(item.n, &item.row, item.last)?;
                        got = true;
                    }
                    if finishing {
                        recorder.flush()?;
                        return Ok(recorder);
                    }
                    if last_flush.elapsed() >= flush_every {
                        recorder.flush()?;
                        last_flush = Instant::now();
                    }
                    if !got {
                        std::thread::sleep(IDLE);
                    }
                }
            })
            .map_err(RecordError::Spawn)?;
        Ok(Self { tx, done, thread: Some(thread), log_every, space: PhantomData })
    }

    /// Hands a row to the thread without waiting; `false` if the ring is full (the row is
    /// dropped). No allocation, no lock, no system call.
    #[inline]
    pub fn try_push(&mut self, item: LogItem<S, N>) -> bool {
        self.tx.push(item).is_ok()
    }

    /// Waits for the thread to write everything and returns the sink.
    ///
    /// # Errors
    /// Writing the file failed, or the thread panicked.
    pub fn finish(mut self) -> Result<K, RecordError> {
        self.join()
    }

    fn join(&mut self) -> Result<K, RecordError> {
        self.done.store(true, Ordering::Release);
        let thread = self.thread.take().ok_or(RecordError::FailedEarlier)?;
        thread.join().map_err(|_| RecordError::Panicked)?
    }
}

impl<K: RowSink<S, N> + Send + 'static, S: Task, const N: usize> RowSink<S, N> for RecordWriter<K, S, N> {
    fn log_every(&self) -> u64 {
        self.log_every
    }

    /// Hands the row to the thread, waiting while the ring is full.
    fn record(&mut self, n: u64, row: &Row<S, N>, last: bool) -> Result<(), RecordError> {
        let mut item = LogItem { n, row: *row, last };
        loop {
            match self.tx.push(item) {
                Ok(()) => return Ok(()),
                Err(rtrb::PushError::Full(back)) => {
                    item = back;
                    if self.thread.as_ref().is_none_or(JoinHandle::is_finished) {
                        // The thread stopped early, so it failed: report why.
                        self.join()?;
                        return Err(RecordError::StoppedEarly);
                    }
                    std::thread::sleep(BACKOFF);
                }
            }
        }
    }
}

impl<K, S: Task, const N: usize> Drop for RecordWriter<K, S, N> {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use companion_core::nalgebra::{SVector, Vector3};
    use companion_core::{Command, PlatformKind, Pose, StepError};

    use super::*;
    use crate::domain::controller::{StepReport, JOINTS};
    use crate::domain::record::recorder::Log;
    use crate::domain::record::{CommandSource, PlantSample, Recorder, SummaryAccumulator};

    fn row(k: u32) -> Row {
        let x = f64::from(k);
        let mut report = StepReport {
            command: Command::zero(),
            ep_norm: 1.0 / (x + 3.0),
            h_s: x.sqrt(),
            psi: 1.0,
            saturation: 1.0,
            alpha_rate: [x * 0.1, -x / 7.0],
            joint_scale: 1.0 + x * 1e-3,
            platform_acceleration: k % 3 == 0,
            joint_acceleration: k % 5 == 0,
            error: None,
        };
        report.command.platform.v = (x * 0.37).sin();
        report.command.platform.omega = -x * 1e-3;
        if k % 97 == 5 {
            report = StepReport::rejected(StepError::SingularArm);
        }
        let plant = PlantSample {
            t: x * 1e-3,
            base: Pose::new(x.cos(), x.sin(), x / 3.0),
            steering: 0.01 * x,
            joints: SVector::<f64, JOINTS>::new(0.1, 0.35 + 1e-5 * x, -0.2),
            end_effector: Pose::new(1.0 / 3.0, x * 1e-7, -x),
            target: Pose::new(2.5, 1.0, 0.0),
            target_velocity: Vector3::new(0.0, -0.157, 0.0),
            e_p: Vector3::new(1.0 / (x + 3.0), 0.0, 0.0),
            ep_norm: 1.0 / (x + 3.0),
        };
        Row { plant, report, source: CommandSource::Fresh }
    }

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("companion-record-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("temporary folder");
        d
    }

    fn recorder(d: &Path, kind: PlatformKind) -> Recorder {
        let summary = SummaryAccumulator::new("test", &[-1.0, 0.0, -1.5], &[1.0, 0.7, 1.5]);
        Recorder { log: Log::create(d, kind, 3, 0).expect("creating the CSV"), summary }
    }

    #[test]
    fn the_writer_thread_writes_the_same_bytes_rows_and_summary() {
        for kind in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
            let (d1, d2) = (dir("direct"), dir("background"));
            let mut direct = recorder(&d1, kind);
            // A small ring: the producer has to wait for room many times.
            let mut background =
                RecordWriter::spawn(recorder(&d2, kind), 64, Duration::from_millis(1)).unwrap();
            let steps = 3 * 128 * 5 + 7;
            for k in 0..=steps {
                direct.record(u64::from(k), &row(k), k == steps).expect("direct");
                background.record(u64::from(k), &row(k), k == steps).expect("background");
            }
            direct.flush().expect("direct");
            let background = background.finish().expect("background");
            let a = std::fs::read(d1.join("timeseries.csv")).expect("read");
            let b = std::fs::read(d2.join("timeseries.csv")).expect("read");
            assert!(a.len() > 100_000, "{}", a.len());
            assert_eq!(a, b, "{kind:?}");
            assert!(String::from_utf8_lossy(&a).contains(",rejected:SingularArm\n"));
            // Debug strings: rejected rows hold NaN.
            assert_eq!(format!("{:?}", direct.log.rows), format!("{:?}", background.log.rows));
            assert_eq!(
                format!("{:?}", direct.summary.finish(0.0)),
                format!("{:?}", background.summary.finish(0.0))
            );
            let _ = std::fs::remove_dir_all(&d1);
            let _ = std::fs::remove_dir_all(&d2);
        }
    }

    #[test]
    fn a_full_ring_drops_without_waiting() {
        let d = dir("full-ring");
        let mut w =
            RecordWriter::spawn(recorder(&d, PlatformKind::Unicycle), 4, Duration::from_secs(1)).unwrap();
        // The thread may drain in between: push until one is refused.
        let refused =
            (0..1_000_000u32).any(|k| !w.try_push(LogItem { n: u64::from(k), row: row(k), last: false }));
        assert!(refused);
        w.finish().unwrap();
        let _ = std::fs::remove_dir_all(&d);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_write_error_of_the_writer_thread_is_reported() {
        // `timeseries.csv` -> /dev/full: every write fails with "no space left on device".
        let d = dir("full");
        std::os::unix::fs::symlink("/dev/full", d.join("timeseries.csv")).expect("symlink");
        let r = Log::create(&d, PlatformKind::Unicycle, 1, 0);
        // The header may already fail (it is buffered: usually not).
        let Ok(r) = r else { return };
        let mut w = RecordWriter::spawn(r, 16, Duration::from_millis(1)).unwrap();
        let mut result = Ok(());
        for k in 0..200_000u32 {
            result = w.record(u64::from(k), &row(k), false);
            if result.is_err() {
                break;
            }
        }
        let err = match result {
            Err(e) => e,
            Ok(()) => w.finish().expect_err("the disk is full"),
        };
        assert!(format!("{err:#}").contains("timeseries.csv"), "{err:#}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
