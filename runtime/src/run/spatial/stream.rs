//! A spatial run's rows on a thread of their own (the HIL plant in real time): the loop hands
//! each logged [`SpatialRecord`] over a lock-free ring allocated once (`rtrb`) and never
//! waits (a full ring drops the row, and the loop counts it); the thread writes it into
//! `timeseries.csv`, flushing every 50 ms — so that the rows up to the last ~50 ms are on
//! disk if the plant is killed — and keeps it for the plots and the replay.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::domain::record::spatial::{SpatialCsv, SpatialRecord};

/// Why the rows of a spatial run could not be streamed into `timeseries.csv`.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The file cannot be created.
    #[error("creating {}", path.display())]
    Create {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The header cannot be written.
    #[error(transparent)]
    Header(csv::Error),
    /// A row cannot be written.
    #[error("writing {}", path.display())]
    Row {
        /// The file.
        path: PathBuf,
        /// The CSV writer's error.
        #[source]
        source: csv::Error,
    },
    /// The file cannot be flushed to the disk.
    #[error("writing {}", path.display())]
    Flush {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The thread cannot be started.
    #[error("starting the CSV writer thread")]
    Spawn(#[source] std::io::Error),
    /// [`SpatialStream::finish`] was called after the thread was joined.
    #[error("the writer was finished twice")]
    FinishedTwice,
    /// The thread panicked.
    #[error("the CSV writer thread panicked")]
    Panicked,
}

/// How often the thread flushes the file.
const FLUSH_EVERY: Duration = Duration::from_millis(50);
/// How long the thread sleeps when the ring is empty.
const IDLE: Duration = Duration::from_millis(2);

/// The loop's end of the writer thread.
#[derive(Debug)]
pub struct SpatialStream {
    tx: rtrb::Producer<SpatialRecord>,
    done: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<Vec<SpatialRecord>, StreamError>>>,
}

impl SpatialStream {
    /// Creates `dir/timeseries.csv` for an arm of `joints` joints and starts the thread with
    /// a ring of `capacity` rows; it keeps up to `expected` rows.
    ///
    /// # Errors
    /// The file cannot be created or the thread started.
    pub fn spawn(dir: &Path, joints: usize, capacity: usize, expected: usize) -> Result<Self, StreamError> {
        let path = dir.join("timeseries.csv");
        let file = match File::create(&path) {
            Ok(f) => f,
            Err(source) => return Err(StreamError::Create { path, source }),
        };
        let mut csv = SpatialCsv::new(BufWriter::new(file), joints).map_err(StreamError::Header)?;
        let (tx, mut rx) = rtrb::RingBuffer::<SpatialRecord>::new(capacity);
        let done = Arc::new(AtomicBool::new(false));
        let finish = Arc::clone(&done);
        let thread = std::thread::Builder::new()
            .name("csv-writer".into())
            .spawn(move || -> Result<Vec<SpatialRecord>, StreamError> {
                let flush = |source| StreamError::Flush { path: path.clone(), source };
                let mut kept = Vec::with_capacity(expected);
                let mut flushed = Instant::now();
                loop {
                    // Read the flag first: rows pushed before it was set are then popped here.
                    let last_round = finish.load(Ordering::Acquire);
                    while let Ok(r) = rx.pop() {
                        csv.write(&r).map_err(|source| StreamError::Row { path: path.clone(), source })?;
                        kept.push(r);
                    }
                    if last_round {
                        csv.flush().map_err(flush)?;
                        return Ok(kept);
                    }
                    if flushed.elapsed() >= FLUSH_EVERY {
                        csv.flush().map_err(flush)?;
                        flushed = Instant::now();
                    }
                    std::thread::sleep(IDLE);
                }
            })
            .map_err(StreamError::Spawn)?;
        Ok(Self { tx, done, thread: Some(thread) })
    }

    /// Hands a row to the thread without waiting; `false` if the ring was full (the row is
    /// dropped).
    #[inline]
    pub fn try_push(&mut self, r: &SpatialRecord) -> bool {
        self.tx.push(*r).is_ok()
    }

    /// Stops the thread after it has written every row handed to it; returns them.
    ///
    /// # Errors
    /// Writing failed, or the thread panicked.
    pub fn finish(mut self) -> Result<Vec<SpatialRecord>, StreamError> {
        self.done.store(true, Ordering::Release);
        let t = self.thread.take().ok_or(StreamError::FinishedTwice)?;
        t.join().map_err(|_| StreamError::Panicked)?
    }
}

impl Drop for SpatialStream {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
