//! What the run prints (semihosting) and how it decides whether the loop closed.

use core::fmt::Write;

/// Periods between two printed lines (100 ms).
pub const EVERY: u32 = 100;

/// A message from the control task to the report task.
#[derive(Clone, Copy, Debug)]
pub enum Report {
    /// `‖e_p‖` after the step of period `k` (at `k` ms).
    Sample {
        /// Period index (ms).
        k: u32,
        /// `‖e_p‖` (m), NaN when the step was rejected.
        e_p: f32,
    },
    /// The run is over.
    End(Tally),
}

/// Counts the control task keeps.
#[derive(Clone, Copy, Debug)]
pub struct Tally {
    /// Periods run.
    pub steps: u32,
    /// Steps the controller rejected (the safe command was applied).
    pub rejected: u32,
    /// Periods in which the plant had not delivered a new state.
    pub stale: u32,
    /// Commands the plant could not take.
    pub dropped: u32,
    /// Samples the report task could not take.
    pub lost: u32,
    /// Longest control task, entry to command (ns, from TIM2's count).
    pub busy_max_ns: u32,
    /// Shortest and longest time between two entries of the control task (ns; QEMU only,
    /// where TIM2's count does not wrap).
    pub period_ns: (u32, u32),
}

impl Tally {
    /// Nothing counted yet.
    pub const ZERO: Self = Self {
        steps: 0,
        rejected: 0,
        stale: 0,
        dropped: 0,
        lost: 0,
        busy_max_ns: 0,
        period_ns: (u32::MAX, 0),
    };
}

/// Judges the run from its samples: the loop closed when the final `‖e_p‖` is below
/// [`Verdict::RATIO`] of the initial one, the worst `‖e_p‖` of each second is no larger
/// than that of the second before (or already below the final threshold), and no step was
/// rejected, no plant state late, no command or sample lost.
#[derive(Debug)]
pub struct Verdict {
    first: Option<f32>,
    last: f32,
    second_max: f32,
    previous_max: Option<f32>,
    rises: u32,
}

impl Verdict {
    /// Final / initial `‖e_p‖` needed.
    pub const RATIO: f32 = 1e-2;

    /// No sample yet.
    pub const fn new() -> Self {
        Self { first: None, last: f32::NAN, second_max: 0.0, previous_max: None, rises: 0 }
    }

    /// Takes the sample of period `k`.
    pub fn sample(&mut self, k: u32, e_p: f32) {
        let first = *self.first.get_or_insert(e_p);
        self.last = e_p;
        // NaN (a rejected step) counts as a rise: `max` would drop it.
        self.second_max =
            if e_p.is_nan() || self.second_max.is_nan() { f32::NAN } else { self.second_max.max(e_p) };
        if k % 1000 == 0 && k > 0 {
            if let Some(prev) = self.previous_max {
                let settled = self.second_max < Self::RATIO * first;
                if !(self.second_max <= prev || settled) {
                    self.rises += 1;
                }
            }
            self.previous_max = Some(self.second_max);
            self.second_max = 0.0;
        }
    }

    /// `(initial, final, seconds in which the worst ‖e_p‖ grew)`.
    pub fn figures(&self) -> (f32, f32, u32) {
        (self.first.unwrap_or(f32::NAN), self.last, self.rises)
    }

    /// Whether the loop closed, given the control task's counts.
    pub fn closed(&self, tally: &Tally) -> bool {
        let (first, last, rises) = self.figures();
        last < Self::RATIO * first
            && rises == 0
            && tally.rejected == 0
            && tally.stale == 0
            && tally.dropped == 0
            && tally.lost == 0
    }
}

/// Writes `k` ms as seconds with three decimals, exactly (integer arithmetic).
pub fn seconds(k: u32) -> Seconds {
    Seconds(k)
}

/// `k` ms printed as `s.mmm`.
#[derive(Clone, Copy, Debug)]
pub struct Seconds(u32);

impl core::fmt::Display for Seconds {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}.{:03}", self.0 / 1000, self.0 % 1000)
    }
}

/// Line-buffered semihosting stdout: one host call per line.
#[derive(Debug)]
pub struct Out {
    buf: [u8; 160],
    len: usize,
}

impl Out {
    /// Empty.
    pub const fn new() -> Self {
        Self { buf: [0; 160], len: 0 }
    }

    fn flush(&mut self) {
        if self.len > 0 {
            if let Ok(mut out) = semihosting::io::stdout() {
                let _ = semihosting::io::Write::write_all(&mut out, &self.buf[..self.len]);
            }
            self.len = 0;
        }
    }
}

impl Write for Out {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            if self.len == self.buf.len() {
                self.flush();
            }
            self.buf[self.len] = b;
            self.len += 1;
            if b == b'\n' {
                self.flush();
            }
        }
        Ok(())
    }
}
