//! A spatial run's rows on a thread of their own (the HIL plant in real time): the loop hands
//! each logged [`SpatialRecord`] over a lock-free ring allocated once (`rtrb`) and never
//! waits (a full ring drops the row, and the loop counts it); the thread writes it into
//! `timeseries.csv`, flushing every 50 ms — so that the rows up to the last ~50 ms are on
//! disk if the plant is killed — and keeps it for the plots and the replay.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};

use crate::domain::record::spatial::{SpatialCsv, SpatialRecord};

/// How often the thread flushes the file.
const FLUSH_EVERY: Duration = Duration::from_millis(50);
/// How long the thread sleeps when the ring is empty.
const IDLE: Duration = Duration::from_millis(2);

/// The loop's end of the writer thread.
#[derive(Debug)]
pub struct SpatialStream {
    tx: rtrb::Producer<SpatialRecord>,
    done: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<Vec<SpatialRecord>>>>,
}

impl SpatialStream {
    /// Creates `dir/timeseries.csv` for an arm of `joints` joints and starts the thread with
    /// a ring of `capacity` rows; it keeps up to `expected` rows.
    ///
    /// # Errors
    /// The file cannot be created or the thread started.
    pub fn spawn(dir: &Path, joints: usize, capacity: usize, expected: usize) -> Result<Self> {
        let path = dir.join("timeseries.csv");
        let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let mut csv = SpatialCsv::new(BufWriter::new(file), joints)?;
        let (tx, mut rx) = rtrb::RingBuffer::<SpatialRecord>::new(capacity);
        let done = Arc::new(AtomicBool::new(false));
        let finish = Arc::clone(&done);
        let thread = std::thread::Builder::new()
            .name("csv-writer".into())
            .spawn(move || -> Result<Vec<SpatialRecord>> {
                let mut kept = Vec::with_capacity(expected);
                let mut flushed = Instant::now();
                loop {
                    // Read the flag first: rows pushed before it was set are then popped here.
                    let last_round = finish.load(Ordering::Acquire);
                    while let Ok(r) = rx.pop() {
                        csv.write(&r).with_context(|| format!("writing {}", path.display()))?;
                        kept.push(r);
                    }
                    if last_round {
                        csv.flush().with_context(|| format!("writing {}", path.display()))?;
                        return Ok(kept);
                    }
                    if flushed.elapsed() >= FLUSH_EVERY {
                        csv.flush().with_context(|| format!("writing {}", path.display()))?;
                        flushed = Instant::now();
                    }
                    std::thread::sleep(IDLE);
                }
            })
            .context("starting the CSV writer thread")?;
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
    pub fn finish(mut self) -> Result<Vec<SpatialRecord>> {
        self.done.store(true, Ordering::Release);
        let t = self.thread.take().ok_or_else(|| anyhow!("the writer was finished twice"))?;
        t.join().map_err(|_| anyhow!("the CSV writer thread panicked"))?
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
