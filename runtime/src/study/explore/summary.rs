//! `summary.json` of an exploration, computed from the lines of `results.csv` in sample order
//! (so that a merged exploration and an unsharded one give the same bytes).

use serde::Serialize;

use super::results::{Class, Record, CLASSES};
use super::space::{Space, INITIAL};
use crate::study::knobs::Knob;

/// Counts per class.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Counts {
    /// Converged.
    pub converged: u64,
    /// Ran to the end without converging.
    pub not_converged: u64,
    /// Diverged (stopped early).
    pub diverged: u64,
    /// A step was rejected.
    pub rejected: u64,
    /// Could not be built.
    pub invalid: u64,
}

/// A few order statistics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Spread {
    /// Values.
    pub count: usize,
    /// Smallest.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Option<Self> {
        v.retain(|x| x.is_finite());
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let q = |p: f64| {
            let i = ((v.len() - 1) as f64 * p).round() as usize;
            v[i]
        };
        Some(Self { count: v.len(), min: v[0], median: q(0.5), p90: q(0.9), max: v[v.len() - 1] })
    }
}

/// The success map: samples and converged samples per cell.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Map {
    /// The horizontal variable.
    pub x: String,
    /// The vertical variable (none: one row).
    pub y: Option<String>,
    /// Bin edges along x.
    pub x_edges: Vec<f64>,
    /// Bin edges along y.
    pub y_edges: Vec<f64>,
    /// `samples[j][i]`: samples in cell (x bin i, y bin j).
    pub samples: Vec<Vec<u64>>,
    /// `converged[j][i]`: of which converged.
    pub converged: Vec<Vec<u64>>,
}

/// The observed bound on `‖e_p‖` in one bin of `ε`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoundBin {
    /// The bin's low edge.
    pub epsilon_low: f64,
    /// The bin's high edge.
    pub epsilon_high: f64,
    /// Samples in the bin that ran to the end.
    pub samples: u64,
    /// The largest `ep_bound` (the largest `‖e_p‖` over the second half of a run).
    pub max_ep_bound: f64,
    /// The median `ep_bound`.
    pub median_ep_bound: f64,
}

/// `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ExploreSummary {
    /// The base scenario's name.
    pub scenario: String,
    /// Samples.
    pub samples: u64,
    /// Seed.
    pub seed: u64,
    /// Per class.
    pub counts: Counts,
    /// `converged / samples`.
    pub converged_fraction: f64,
    /// Settling times of the converged samples (s).
    pub settling_time_s: Option<Spread>,
    /// Tracked fractions over the second half, all samples.
    pub tracked_fraction: Option<Spread>,
    /// Smallest joint margins (rad or m), all samples.
    pub min_joint_margin: Option<Spread>,
    /// The success map.
    pub map: Map,
    /// The variable the bound is binned by (`epsilon`, `epsilon_1`), if any.
    pub size: Option<String>,
    /// The observed practical-stability bound on `‖e_p‖` against it.
    pub ep_bound_by_size: Vec<BoundBin>,
}

/// The column index of variable `name` among a record's inputs.
pub fn input_index(name: &str, knobs: &[Knob]) -> Option<usize> {
    INITIAL
        .iter()
        .position(|n| *n == name)
        .or_else(|| knobs.iter().position(|k| k.name() == name).map(|i| INITIAL.len() + i))
}

fn edges(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|i| lo + (hi - lo) * i as f64 / n as f64).collect()
}

fn bin(v: f64, e: &[f64]) -> Option<usize> {
    let n = e.len() - 1;
    if !(v >= e[0] && v <= e[n]) {
        return None;
    }
    let i = (((v - e[0]) / (e[n] - e[0])) * n as f64).floor() as usize;
    Some(i.min(n - 1))
}

/// The range of a variable of the space.
fn range_of(space: &Space, name: &str) -> (f64, f64) {
    if let Some(i) = INITIAL.iter().position(|n| *n == name) {
        return space.initial[i].map_or((0.0, 1.0), |v| v.bounds());
    }
    space.parameters.iter().find(|(k, _)| k.name() == name).map_or((0.0, 1.0), |(_, v)| v.bounds())
}

/// The summary of `records` (in sample order).
pub fn summarize(
    scenario: &str,
    seed: u64,
    space: &Space,
    knobs: &[Knob],
    size: Option<Knob>,
    records: &[Record],
) -> ExploreSummary {
    let mut counts = Counts::default();
    for r in records {
        match r.class {
            Class::Converged => counts.converged += 1,
            Class::NotConverged => counts.not_converged += 1,
            Class::Diverged => counts.diverged += 1,
            Class::Rejected => counts.rejected += 1,
            Class::Invalid => counts.invalid += 1,
        }
    }
    debug_assert_eq!(CLASSES.len(), 5);
    let n = records.len() as u64;
    let converged_fraction = if n > 0 { counts.converged as f64 / n as f64 } else { 0.0 };
    let col = |name: &str, only: Option<Class>| -> Vec<f64> {
        records.iter().filter(|r| only.is_none_or(|c| r.class == c)).map(|r| r.outcome(name)).collect()
    };
    // The map.
    let m = &space.map;
    let (xl, xh) = range_of(space, &m.x);
    let (yl, yh) = m.y.as_deref().map_or((0.0, 1.0), |y| range_of(space, y));
    let ny = if m.y.is_some() { m.bins[1] } else { 1 };
    let (x_edges, y_edges) = (edges(xl, xh, m.bins[0]), edges(yl, yh, ny));
    let mut samples = vec![vec![0u64; m.bins[0]]; ny];
    let mut converged = samples.clone();
    let xi = input_index(&m.x, knobs);
    let yi = m.y.as_deref().map(|y| input_index(y, knobs));
    for r in records {
        let Some(xi) = xi else { break };
        let y = match yi {
            None => 0.5,
            Some(Some(yi)) => r.inputs[yi],
            Some(None) => break,
        };
        if let (Some(i), Some(j)) = (bin(r.inputs[xi], &x_edges), bin(y, &y_edges)) {
            samples[j][i] += 1;
            converged[j][i] += u64::from(r.class == Class::Converged);
        }
    }
    // The bound on ‖e_p‖ against the size of the transverse function.
    let mut ep_bound_by_size = Vec::new();
    if let Some(k) = size {
        if let Some(si) = input_index(k.name(), knobs) {
            let ran: Vec<&Record> = records
                .iter()
                .filter(|r| matches!(r.class, Class::Converged | Class::NotConverged))
                .collect();
            let (lo, hi) = range_of(space, k.name());
            let (lo, hi, nb) = if hi > lo { (lo, hi, 10) } else { (lo, hi, 1) };
            let e = if nb == 1 { vec![lo, hi] } else { edges(lo, hi, nb) };
            for b in 0..nb {
                let in_bin: Vec<f64> = ran
                    .iter()
                    .filter(|r| nb == 1 || bin(r.inputs[si], &e) == Some(b))
                    .map(|r| r.outcome("ep_bound"))
                    .collect();
                let s = Spread::of(in_bin.clone());
                ep_bound_by_size.push(BoundBin {
                    epsilon_low: e[b],
                    epsilon_high: e[b + 1],
                    samples: in_bin.len() as u64,
                    max_ep_bound: s.as_ref().map_or(f64::NAN, |s| s.max),
                    median_ep_bound: s.as_ref().map_or(f64::NAN, |s| s.median),
                });
            }
        }
    }
    ExploreSummary {
        scenario: scenario.to_string(),
        samples: n,
        seed,
        counts,
        converged_fraction,
        settling_time_s: Spread::of(col("settling_time_s", Some(Class::Converged))),
        tracked_fraction: Spread::of(col("tracked_fraction", None)),
        min_joint_margin: Spread::of(col("min_joint_margin", None)),
        map: Map { x: m.x.clone(), y: m.y.clone(), x_edges, y_edges, samples, converged },
        size: size.map(|k| k.name().to_string()),
        ep_bound_by_size,
    }
}
