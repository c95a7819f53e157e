//! `results.csv`: one line per sample, each ending in a checksum of the line, so that a line
//! cut short by a kill or altered afterwards is recognised wherever it is read (resuming,
//! merging shards).
//!
//! ```text
//! sample,distance,…,steering,<knobs>,class,tracked_fraction,settling_time_s,final_ep_norm,
//! ep_bound,min_joint_margin,max_abs_v,time_saturated_s,rejected_steps,maneuvers,check
//! ```
//!
//! Numbers are written with Rust's shortest round-trip formatting: the same value always
//! gives the same text, and the text parses back to the same bits. `check` is the FNV-1a
//! 64-bit hash of everything before the last comma, in 16 hexadecimal digits.

use std::fmt::Write as _;

use serde::Serialize;

use super::space::{Space, INITIAL};
use crate::study::knobs::Knob;
use crate::study::trial::{Figures, Judge, Tail};

/// Why a line of a results file is not one.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    /// The line has no comma, so no checksum.
    #[error("not a results line")]
    NotALine,
    /// The checksum does not match the line.
    #[error("checksum {found} does not match the line (expected {expected})")]
    Checksum {
        /// The line's checksum.
        found: String,
        /// The line's hash.
        expected: String,
    },
    /// The line has the wrong number of fields.
    #[error("{found} fields, expected {expected}")]
    Fields {
        /// The line's fields.
        found: usize,
        /// The file's columns.
        expected: usize,
    },
    /// A field that should be a number is not.
    #[error("`{0}` is not a number")]
    NotANumber(String),
    /// The first field is not a sample index.
    #[error("`{0}` is not a sample index")]
    NotASample(String),
    /// The class field is not a class.
    #[error("unknown class `{0}`")]
    UnknownClass(String),
}

/// Why a results file (`results.csv`, `journal.csv`) cannot be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ResultsError {
    /// The file's header is not this exploration's.
    #[error(
        "{what}: its header differs from this exploration's:\n  found:    {found}\n  expected: {expected}"
    )]
    Header {
        /// The file.
        what: String,
        /// Its header.
        found: String,
        /// This exploration's.
        expected: String,
    },
    /// A complete line is corrupt.
    #[error("{what}, line {line}: corrupt ({cause}); not used")]
    Corrupt {
        /// The file.
        what: String,
        /// The line's number (the header is line 1).
        line: usize,
        /// What is wrong with it.
        cause: LineError,
    },
}

/// How a sample ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// `‖e_p‖` within the tolerance over the final window, no step rejected.
    Converged,
    /// Ran to the end without converging (bounded, or still on its way).
    NotConverged,
    /// `‖e_p‖` passed the divergence bound; the run was stopped.
    Diverged,
    /// The controller rejected at least one step (never counted as converged).
    Rejected,
    /// The sample's scenario could not be built (should not happen after the space's check).
    Invalid,
}

/// Every class, in summary order.
pub const CLASSES: [Class; 5] =
    [Class::Converged, Class::NotConverged, Class::Diverged, Class::Rejected, Class::Invalid];

impl Class {
    /// As written in `results.csv`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::NotConverged => "not_converged",
            Self::Diverged => "diverged",
            Self::Rejected => "rejected",
            Self::Invalid => "invalid",
        }
    }

    fn parse(s: &str) -> Option<Self> {
        CLASSES.into_iter().find(|c| c.name() == s)
    }

    /// The class of a trial, from its figures and tail.
    pub fn of(figures: &Figures, tail: &Tail, judge: &Judge) -> Self {
        if figures.rejected_steps > 0 {
            Self::Rejected
        } else if tail.diverged_at.is_some() {
            Self::Diverged
        } else if tail.converged(figures.rejected_steps, judge) {
            Self::Converged
        } else {
            Self::NotConverged
        }
    }
}

/// The outcome columns after `class`.
pub const OUTCOMES: [&str; 10] = [
    "tracked_fraction",
    "settling_time_s",
    "final_ep_norm",
    "ep_bound",
    "min_joint_margin",
    "max_abs_v",
    "time_saturated_s",
    "rejected_steps",
    "maneuvers",
    "check",
];

/// One parsed line.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// The sample's index.
    pub sample: u64,
    /// The input columns' values (initial variables, then the knobs).
    pub inputs: Vec<f64>,
    /// The class.
    pub class: Class,
    /// The outcome columns' values, `check` excepted.
    pub outcomes: [f64; 9],
}

impl Record {
    /// An outcome by column name.
    pub fn outcome(&self, name: &str) -> f64 {
        OUTCOMES.iter().position(|c| *c == name).map_or(f64::NAN, |i| self.outcomes[i])
    }
}

/// The knob columns of a space: its knobs, and the platform's size (`epsilon` or `epsilon_1`)
/// even when it is fixed (the bound on `‖e_p‖` is plotted against it).
pub fn knob_columns(space: &Space, size: Option<Knob>) -> Vec<Knob> {
    let mut k: Vec<Knob> = space.parameters.iter().map(|(k, _)| *k).collect();
    if let Some(s) = size {
        if !k.contains(&s) {
            k.push(s);
            k.sort();
        }
    }
    k
}

/// The header line (without a line break).
pub fn header(knobs: &[Knob]) -> String {
    let mut cols: Vec<&str> = vec!["sample"];
    cols.extend(INITIAL);
    cols.extend(knobs.iter().map(|k| k.name()));
    cols.push("class");
    cols.extend(OUTCOMES);
    cols.join(",")
}

/// FNV-1a, 64 bits (the wire's: one implementation for every hash of the runtime).
pub use crate::transport::wire::fnv1a;

/// The line of a sample (without a line break), from its run's figures and tail.
pub fn line(sample: u64, inputs: &[f64], class: Class, ran: Option<(&Figures, &Tail)>) -> String {
    let mut s = format!("{sample}");
    for v in inputs {
        let _ = write!(s, ",{v}");
    }
    let _ = write!(s, ",{}", class.name());
    match ran {
        Some((m, tail)) => {
            let _ = write!(
                s,
                ",{},{},{},{},{},{},{},{},{}",
                tail.tracked_fraction,
                tail.settling_time_s,
                m.final_ep_norm,
                tail.ep_bound,
                m.min_joint_margin,
                m.max_abs_v,
                tail.time_saturated_s,
                m.rejected_steps,
                m.maneuvers,
            );
        }
        None => s.push_str(",NaN,NaN,NaN,NaN,NaN,NaN,NaN,0,0"),
    }
    let check = fnv1a(s.as_bytes());
    let _ = write!(s, ",{check:016x}");
    s
}

/// Parses and verifies one line of a file with `columns` columns.
///
/// # Errors
/// The wrong number of fields, a checksum that does not match, or a field that does not
/// parse.
pub fn parse(text: &str, columns: usize) -> Result<Record, LineError> {
    let Some((body, check)) = text.rsplit_once(',') else { return Err(LineError::NotALine) };
    let expected = format!("{:016x}", fnv1a(body.as_bytes()));
    if check != expected {
        return Err(LineError::Checksum { found: check.to_string(), expected });
    }
    let fields: Vec<&str> = text.split(',').collect();
    if fields.len() != columns {
        return Err(LineError::Fields { found: fields.len(), expected: columns });
    }
    let num = |s: &str| s.parse::<f64>().map_err(|_| LineError::NotANumber(s.to_string()));
    let sample = fields[0].parse::<u64>().map_err(|_| LineError::NotASample(fields[0].to_string()))?;
    let n_in = columns - 1 - 1 - OUTCOMES.len();
    let inputs = fields[1..=n_in].iter().map(|s| num(s)).collect::<Result<Vec<_>, _>>()?;
    let class = Class::parse(fields[1 + n_in])
        .ok_or_else(|| LineError::UnknownClass(fields[1 + n_in].to_string()))?;
    let mut outcomes = [0.0; 9];
    for (i, o) in outcomes.iter_mut().enumerate() {
        *o = num(fields[2 + n_in + i])?;
    }
    Ok(Record { sample, inputs, class, outcomes })
}

/// Verified lines of a results file: `(sample, line)` each, and a last line cut short.
pub type Lines = (Vec<(u64, String)>, Option<String>);

/// The complete lines of a file's text after its header, verified, with the index of each;
/// a last line without its line break (a write cut short by a kill) is returned apart.
///
/// # Errors
/// The header differs, or a complete line is corrupt (named by its line number).
pub fn read_lines(text: &str, header: &str, what: &str) -> Result<Lines, ResultsError> {
    let columns = header.split(',').count();
    let mut lines = text.split_inclusive('\n');
    match lines.next() {
        Some(h) if h.trim_end_matches('\n') == header => {}
        Some(h) => {
            return Err(ResultsError::Header {
                what: what.to_string(),
                found: h.trim_end().to_string(),
                expected: header.to_string(),
            })
        }
        None => return Ok((Vec::new(), None)),
    }
    let mut out = Vec::new();
    let mut cut = None;
    for (i, l) in lines.enumerate() {
        let Some(body) = l.strip_suffix('\n') else {
            cut = Some(l.to_string());
            break;
        };
        let rec = parse(body, columns).map_err(|cause| ResultsError::Corrupt {
            what: what.to_string(),
            line: i + 2,
            cause,
        })?;
        out.push((rec.sample, body.to_string()));
    }
    Ok((out, cut))
}
