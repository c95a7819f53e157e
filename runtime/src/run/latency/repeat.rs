//! `companion latency --repeat N`: a verdict that survives a rerun.
//!
//! On a shared machine one run per wait mode is not evidence: the machine's load drifts
//! between runs, and a mode measured in a quiet minute beats one measured in a busy one. So
//! the HIL contenders (each wait mode, and with `--release-timers` the plant's release
//! timers) and the paced bare transport run in *rounds*, interleaved — under each load of
//! the round, contender A, B, C, then the bare transport; then the next round — so that the
//! drift falls on all of them alike. Each run's misses are set against the bare transport's
//! *of the same round and load* ([`HilRun::beyond_bare`]).
//!
//! Per contender and load, over the rounds ([`Cell`]): the distribution ([`Spread`]: median,
//! interquartile range, best and worst run) of the misses, of the misses beyond the bare
//! transport, of the plant's and the controller's misses, and of the round trip's p50 and
//! p99.9; the controller's late wakes summed by cause ([`crate::run::hil::wakes`]). The
//! default wait mode is held to issue 39's aims ([`Aim`]). [`Repeated::markdown`] is the
//! table for the docs; [`Repeated::plot`] the box plot.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::figures::{ControllerFigures, HilFigures, Load};
use crate::domain::histogram::{fmt_ns, Percentiles};
use crate::domain::plots::{boxes_svg, BoxPanel, BoxSeries, PlotError};
use crate::domain::spread::Spread;
use crate::run::hil::misses::MissCauses;
use crate::run::hil::wakes::LateWakes;
use crate::run::hil::{ReleaseTimer, WaitMode};

/// One contender of the HIL runs: a wait mode and the plant's release timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Contender {
    /// `--wait`.
    pub wait: WaitMode,
    /// `--release-timer`.
    pub release: ReleaseTimer,
}

impl Contender {
    /// The wait mode's name, and the release timer's if it is not the default (`event+timerfd`).
    pub fn label(&self) -> String {
        if self.release == ReleaseTimer::default() {
            self.wait.as_str().to_string()
        } else {
            format!("{}+{}", self.wait.as_str(), self.release.as_str())
        }
    }

    /// The contenders of `modes` and `timers`: each mode that sleeps to the plant's release
    /// ([`WaitMode::sleeps_to_release`]) with each timer, each other mode once (with the
    /// default timer, which it does not use).
    pub fn all(modes: &[WaitMode], timers: &[ReleaseTimer]) -> Vec<Self> {
        let mut out = Vec::new();
        for &wait in modes {
            if wait.sleeps_to_release() && !timers.is_empty() {
                out.extend(timers.iter().map(|&release| Self { wait, release }));
            } else {
                out.push(Self { wait, release: ReleaseTimer::default() });
            }
        }
        out.dedup();
        out
    }
}

/// One HIL run of one round.
#[derive(Clone, Debug, Serialize)]
pub struct HilRun {
    /// The round (from 1).
    pub round: u32,
    /// The load.
    pub load: Load,
    /// The contender's label.
    pub label: String,
    /// The contender.
    pub contender: Contender,
    /// Deadline misses.
    pub misses: u64,
    /// The bare transport's round trips over the deadline, same round and load.
    pub bare_misses: u64,
    /// `misses − bare_misses`.
    pub beyond_bare: i64,
    /// The misses by cause (`latency.json`).
    pub causes: MissCauses,
    /// The round trip (ns).
    pub round_trip_ns: Percentiles,
    /// The plant's release jitter (ns).
    pub release_jitter_ns: Percentiles,
    /// Robot stops.
    pub stop_events: u64,
    /// Whether the plant's loop ran under `SCHED_FIFO`.
    pub fifo: bool,
    /// The controller's side (`controller.json`; `None` if it wrote none).
    pub controller: Option<ControllerFigures>,
    /// The run's folder.
    pub dir: PathBuf,
}

impl HilRun {
    /// Run `f` of `contender` in `round` under `load`, against the bare transport's
    /// `bare_misses` of the same round and load.
    pub fn new(
        round: u32,
        load: Load,
        contender: Contender,
        f: &HilFigures,
        controller: Option<ControllerFigures>,
        bare_misses: u64,
        dir: PathBuf,
    ) -> Self {
        Self {
            round,
            load,
            label: contender.label(),
            contender,
            misses: f.deadline_misses,
            bare_misses,
            beyond_bare: signed(f.deadline_misses) - signed(bare_misses),
            causes: f.miss_causes,
            round_trip_ns: f.round_trip_ns,
            release_jitter_ns: f.release_jitter_ns,
            stop_events: f.stop_events,
            fifo: f.rt.fifo,
            controller,
            dir,
        }
    }
}

fn signed(n: u64) -> i64 {
    i64::try_from(n).unwrap_or(i64::MAX)
}

/// The paced bare transport's run of one round under one load.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BareRun {
    /// The round (from 1).
    pub round: u32,
    /// The load.
    pub load: Load,
    /// Round trips over the deadline.
    pub over_deadline: u64,
    /// The round trip (ns).
    pub round_trip_ns: Percentiles,
}

/// One contender (or the bare transport) under one load, over the rounds.
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    /// The contender's label, or `bare iceoryx2`.
    pub label: String,
    /// The contender (`None`: the bare transport).
    pub contender: Option<Contender>,
    /// The load.
    pub load: Load,
    /// Misses per run.
    pub misses: Spread,
    /// Misses beyond the bare transport's of the same round (contenders only).
    pub beyond_bare: Option<Spread>,
    /// The plant's misses per run (`plant_late`; contenders only).
    pub plant_misses: Option<Spread>,
    /// The controller's misses per run (`controller_wake + controller_compute`).
    pub controller_misses: Option<Spread>,
    /// The round trip's median per run (ns).
    pub round_trip_p50_ns: Spread,
    /// The round trip's p99.9 per run (ns).
    pub round_trip_p99_9_ns: Spread,
    /// The controller's late wakes over all runs, by cause.
    pub late_wakes: Option<LateWakes>,
    /// The plant's count of the controller's misses over the runs that have a
    /// `controller.json` (`controller_wake + controller_compute`), to set against the
    /// controller's own count ([`LateWakes::missed`]). They need not match: the plant's
    /// deadline runs from the release, the controller's from the publication stamp; the plant
    /// puts a period down to its own late release first; and it takes a command that came
    /// after the deadline as fresh if it looked for it no sooner itself.
    pub plant_counted_controller: u64,
    /// Runs in which the robot was stopped.
    pub runs_with_stops: u64,
}

/// One of issue 39's aims for the default wait mode, judged on the medians.
#[derive(Clone, Debug, Serialize)]
pub struct Aim {
    /// What is aimed at.
    pub aim: String,
    /// The measured figures.
    pub measured: String,
    /// Met (`None`: a figure to report, not an aim; or not measured).
    pub met: Option<bool>,
}

/// The repeated runs (`latency-benchmark.json` `repeated`).
#[derive(Clone, Debug, Serialize)]
pub struct Repeated {
    /// Rounds.
    pub rounds: u32,
    /// Cycles per run.
    pub cycles: u64,
    /// The deadline (ns).
    pub deadline_ns: u64,
    /// The default wait mode (and timer): the one the aims concern.
    pub default: Contender,
    /// Each cell, load by load, contenders in order, the bare transport last.
    pub cells: Vec<Cell>,
    /// The aims.
    pub aims: Vec<Aim>,
    /// Every HIL run.
    pub runs: Vec<HilRun>,
    /// Every bare transport run.
    pub bare: Vec<BareRun>,
}

/// The bare transport's label.
pub const BARE: &str = "bare iceoryx2";

fn spread(v: impl Iterator<Item = f64>) -> Option<Spread> {
    Spread::of(&v.collect::<Vec<_>>())
}

impl Repeated {
    /// The spreads and aims of `runs` and `bare` (`rounds` of `cycles` each).
    pub fn new(
        rounds: u32,
        cycles: u64,
        deadline_ns: u64,
        default: Contender,
        runs: Vec<HilRun>,
        bare: Vec<BareRun>,
    ) -> Self {
        let mut loads: Vec<Load> = Vec::new();
        for l in runs.iter().map(|r| r.load).chain(bare.iter().map(|b| b.load)) {
            if !loads.contains(&l) {
                loads.push(l);
            }
        }
        let mut contenders: Vec<Contender> = Vec::new();
        for c in runs.iter().map(|r| r.contender) {
            if !contenders.contains(&c) {
                contenders.push(c);
            }
        }
        let mut cells = Vec::new();
        for &load in &loads {
            for &c in &contenders {
                let rs: Vec<&HilRun> = runs.iter().filter(|r| r.load == load && r.contender == c).collect();
                if let Some(cell) = Self::cell(c, load, &rs) {
                    cells.push(cell);
                }
            }
            let bs: Vec<&BareRun> = bare.iter().filter(|b| b.load == load).collect();
            let misses = spread(bs.iter().map(|b| b.over_deadline as f64));
            let p50 = spread(bs.iter().map(|b| b.round_trip_ns.p50 as f64));
            let p999 = spread(bs.iter().map(|b| b.round_trip_ns.p99_9 as f64));
            if let (Some(misses), Some(p50), Some(p999)) = (misses, p50, p999) {
                cells.push(Cell {
                    label: BARE.to_string(),
                    contender: None,
                    load,
                    misses,
                    beyond_bare: None,
                    plant_misses: None,
                    controller_misses: None,
                    round_trip_p50_ns: p50,
                    round_trip_p99_9_ns: p999,
                    late_wakes: None,
                    plant_counted_controller: 0,
                    runs_with_stops: 0,
                });
            }
        }
        let mut r = Self { rounds, cycles, deadline_ns, default, cells, aims: Vec::new(), runs, bare };
        r.aims = r.judge();
        r
    }

    fn cell(c: Contender, load: Load, rs: &[&HilRun]) -> Option<Cell> {
        let controller = rs.iter().filter_map(|r| r.controller).collect::<Vec<_>>();
        Some(Cell {
            label: c.label(),
            contender: Some(c),
            load,
            misses: spread(rs.iter().map(|r| r.misses as f64))?,
            beyond_bare: spread(rs.iter().map(|r| r.beyond_bare as f64)),
            plant_misses: spread(rs.iter().map(|r| r.causes.plant_late as f64)),
            controller_misses: spread(rs.iter().map(|r| r.causes.controller() as f64)),
            round_trip_p50_ns: spread(rs.iter().map(|r| r.round_trip_ns.p50 as f64))?,
            round_trip_p99_9_ns: spread(rs.iter().map(|r| r.round_trip_ns.p99_9 as f64))?,
            late_wakes: (!controller.is_empty())
                .then(|| controller.iter().fold(LateWakes::default(), |a, f| a.sum(&f.wakes.late_wakes))),
            plant_counted_controller: rs
                .iter()
                .filter(|r| r.controller.is_some())
                .map(|r| r.causes.controller())
                .sum(),
            runs_with_stops: rs.iter().filter(|r| r.stop_events > 0).count() as u64,
        })
    }

    /// The cell of `label` under `load`.
    pub fn cell_of(&self, label: &str, load: Load) -> Option<&Cell> {
        self.cells.iter().find(|c| c.label == label && c.load == load)
    }

    /// Issue 39's aims for the default, on the medians: idle, no misses beyond the bare
    /// transport; busy, no more misses than the bare transport; the round-trip medians side
    /// by side; and, per load, the contender that misses least.
    fn judge(&self) -> Vec<Aim> {
        let d = self.default.label();
        let mut aims = Vec::new();
        if let Some(c) = self.cell_of(&d, Load::Idle) {
            if let Some(b) = c.beyond_bare {
                aims.push(Aim {
                    aim: format!("{d}, idle: median of the misses beyond the bare transport ≤ 0"),
                    measured: format!("{} (IQR {}–{}, worst {})", n(b.median), n(b.q1), n(b.q3), n(b.worst)),
                    met: Some(b.median <= 0.0),
                });
            }
        }
        if let (Some(c), Some(b)) = (self.cell_of(&d, Load::Busy), self.cell_of(BARE, Load::Busy)) {
            aims.push(Aim {
                aim: format!("{d}, busy: median misses ≤ the bare transport's"),
                measured: format!("{} against {}", n(c.misses.median), n(b.misses.median)),
                met: Some(c.misses.median <= b.misses.median),
            });
        }
        for load in [Load::Idle, Load::Busy] {
            let (Some(c), Some(b)) = (self.cell_of(&d, load), self.cell_of(BARE, load)) else { continue };
            aims.push(Aim {
                aim: format!("{d}, {}: round-trip p50 beside the bare transport's", load.as_str()),
                measured: format!(
                    "{} against {} ({:.1}×)",
                    ns(c.round_trip_p50_ns.median),
                    ns(b.round_trip_p50_ns.median),
                    c.round_trip_p50_ns.median / b.round_trip_p50_ns.median.max(1.0)
                ),
                met: None,
            });
            let least = self
                .cells
                .iter()
                .filter(|x| x.load == load && x.contender.is_some())
                .min_by(|x, y| x.misses.median.total_cmp(&y.misses.median));
            if let Some(l) = least.filter(|l| l.label != d) {
                let slower = l.round_trip_p50_ns.median > c.round_trip_p50_ns.median;
                aims.push(Aim {
                    aim: format!("{}: the contender that misses least", load.as_str()),
                    measured: format!(
                        "{} (median {} misses against the default's {}){}",
                        l.label,
                        n(l.misses.median),
                        n(c.misses.median),
                        if slower {
                            format!(
                                ", at a higher round-trip median ({} against {}): deadlines first",
                                ns(l.round_trip_p50_ns.median),
                                ns(c.round_trip_p50_ns.median)
                            )
                        } else {
                            String::new()
                        }
                    ),
                    met: None,
                });
            }
        }
        aims
    }

    /// The table for the docs, in Markdown, with the command that made it.
    pub fn markdown(&self, command: &str, machine: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} interleaved round(s) of {} cycles per run at 1 kHz, deadline {}; `{command}`; {machine}.\n",
            self.rounds,
            self.cycles,
            fmt_ns(self.deadline_ns)
        );
        s.push_str(
            "| wait | load | misses per run | beyond the bare transport | plant's / controller's | round trip p50 | \
             round trip p99.9 |\n|---|---|---|---|---|---|---|\n",
        );
        for c in &self.cells {
            let name = if c.contender == Some(self.default) {
                format!("**{}** (default)", c.label)
            } else if c.contender.is_none() {
                format!("{} (paced, busy-poll)", c.label)
            } else {
                c.label.clone()
            };
            let whose = match (c.plant_misses, c.controller_misses) {
                (Some(p), Some(k)) => format!("{} / {}", n(p.median), n(k.median)),
                _ => "—".to_string(),
            };
            let _ = writeln!(
                s,
                "| {name} | {} | {} | {} | {whose} | {} | {} |",
                c.load.as_str(),
                counts(&c.misses),
                c.beyond_bare.as_ref().map_or("—".to_string(), signed_counts),
                times(&c.round_trip_p50_ns),
                times(&c.round_trip_p99_9_ns),
            );
        }
        s.push_str(
            "\nEach cell: the median over the runs, [the interquartile range], (the worst run). \"Beyond \
             the bare transport\": a run's misses less those of the bare iceoryx2 ping-pong paced at 1 kHz \
             in the same round under the same load; \"plant's / controller's\": medians of `latency.json` \
             `miss_causes` (`plant_late`; `controller_wake + controller_compute`).\n",
        );
        let late: Vec<String> = self
            .cells
            .iter()
            .filter_map(|c| {
                let w = c.late_wakes?;
                let causes: Vec<String> = w
                    .causes()
                    .iter()
                    .filter(|(_, k)| k.wakes > 0)
                    .map(|(name, k)| format!("{} {} ({} missed)", name.replace('_', " "), k.wakes, k.missed))
                    .collect();
                Some(format!(
                    "{} {}: {} — {} periods missed by its own count, {} by the plant's",
                    c.label,
                    c.load.as_str(),
                    if causes.is_empty() { "none".to_string() } else { causes.join(", ") },
                    w.missed(),
                    c.plant_counted_controller
                ))
            })
            .collect();
        if !late.is_empty() {
            let _ = writeln!(
                s,
                "\nThe controller's late wakes (over half the deadline) in all runs, by what it was doing \
                 (`controller.json`), and the periods missed through the controller by its own count against \
                 the plant's (`controller_wake + controller_compute`; they need not match: the plant puts a \
                 period down to its own late release first, and judges from the release, not the stamp): {}.",
                late.join("; ")
            );
        }
        if !self.aims.is_empty() {
            s.push('\n');
            for a in &self.aims {
                let verdict = match a.met {
                    Some(true) => " — **met**",
                    Some(false) => " — **not met**",
                    None => "",
                };
                let _ = writeln!(s, "- {}: {}{verdict}", a.aim, a.measured);
            }
        }
        s
    }

    /// The box plot: a column per load, rows of misses per run, misses beyond the bare
    /// transport, round-trip p50 and p99.9; a box per contender and the bare transport.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn plot(&self, path: &Path) -> Result<(), PlotError> {
        let mut loads: Vec<Load> = Vec::new();
        for c in &self.cells {
            if !loads.contains(&c.load) {
                loads.push(c.load);
            }
        }
        // Each box's values, per row and load.
        type Pick = fn(&Repeated, &Cell) -> Vec<f64>;
        let rows: [(&str, &str, Pick); 4] = [
            ("misses per run", "misses", |r, c| r.values(c, |h| h.misses as f64, |b| b.over_deadline as f64)),
            ("misses beyond the bare transport (same round)", "misses", |r, c| {
                r.values(c, |h| h.beyond_bare as f64, |_| f64::NAN)
            }),
            ("round trip p50 per run", "µs", |r, c| {
                r.values(c, |h| h.round_trip_ns.p50 as f64 / 1e3, |b| b.round_trip_ns.p50 as f64 / 1e3)
            }),
            ("round trip p99.9 per run", "ms", |r, c| {
                r.values(c, |h| h.round_trip_ns.p99_9 as f64 / 1e6, |b| b.round_trip_ns.p99_9 as f64 / 1e6)
            }),
        ];
        // (title, y axis, each box's label and values)
        type Panel<'y> = (String, &'y str, Vec<(String, Vec<f64>)>);
        let mut values: Vec<Panel<'_>> = Vec::new();
        for (title, y, pick) in rows {
            for &load in &loads {
                // (The bare transport has no misses beyond its own: no box there.)
                let boxes = self
                    .cells
                    .iter()
                    .filter(|c| c.load == load)
                    .map(|c| {
                        (
                            c.label.clone(),
                            pick(self, c).into_iter().filter(|v| v.is_finite()).collect::<Vec<_>>(),
                        )
                    })
                    .filter(|(_, v)| !v.is_empty())
                    .collect();
                values.push((format!("{title}, {}", load.as_str()), y, boxes));
            }
        }
        let panels: Vec<BoxPanel<'_>> = values
            .iter()
            .map(|(title, y, boxes)| BoxPanel {
                title: title.clone(),
                y_desc: y,
                boxes: boxes.iter().map(|(l, v)| BoxSeries { label: l, values: v }).collect(),
            })
            .collect();
        boxes_svg(
            path,
            &format!(
                "companion latency --repeat {}: {} cycles per run, one dot per run, whiskers to the best and worst",
                self.rounds, self.cycles
            ),
            &panels,
            loads.len(),
        )
    }

    /// The per-run values of `c`: its HIL runs' by `hil`, or the bare transport's by `bare`.
    fn values(&self, c: &Cell, hil: impl Fn(&HilRun) -> f64, bare: impl Fn(&BareRun) -> f64) -> Vec<f64> {
        match c.contender {
            Some(k) => self.runs.iter().filter(|r| r.load == c.load && r.contender == k).map(hil).collect(),
            None => self.bare.iter().filter(|b| b.load == c.load).map(bare).collect(),
        }
    }
}

/// A count, as an integer when it is one.
fn n(x: f64) -> String {
    if x.fract() == 0.0 {
        format!("{x:.0}")
    } else {
        format!("{x:.1}")
    }
}

/// `median [q1–q3] (worst)` of counts.
fn counts(s: &Spread) -> String {
    format!("{} [{}–{}] ({})", n(s.median), n(s.q1), n(s.q3), n(s.worst))
}

/// The same with signs.
fn signed_counts(s: &Spread) -> String {
    let sg = |x: f64| if x > 0.0 { format!("+{}", n(x)) } else { n(x) };
    format!("{} [{}–{}] ({})", sg(s.median), sg(s.q1), sg(s.q3), sg(s.worst))
}

fn ns(x: f64) -> String {
    fmt_ns(x.max(0.0).round() as u64)
}

/// `median [q1–q3] (worst)` of times.
fn times(s: &Spread) -> String {
    format!("{} [{}–{}] ({})", ns(s.median), ns(s.q1), ns(s.q3), ns(s.worst))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn percentiles(p50: u64) -> Percentiles {
        Percentiles { count: 10_000, p50, p99_9: 10 * p50, max: 100 * p50, ..Percentiles::default() }
    }

    fn run(round: u32, load: Load, wait: WaitMode, misses: u64, bare: u64, p50: u64) -> HilRun {
        HilRun {
            round,
            load,
            label: wait.as_str().into(),
            contender: Contender { wait, release: ReleaseTimer::default() },
            misses,
            bare_misses: bare,
            beyond_bare: misses as i64 - bare as i64,
            causes: MissCauses {
                plant_late: misses / 2,
                controller_wake: misses - misses / 2,
                ..MissCauses::default()
            },
            round_trip_ns: percentiles(p50),
            release_jitter_ns: Percentiles::default(),
            stop_events: u64::from(misses > 1_000),
            fifo: false,
            controller: None,
            dir: PathBuf::new(),
        }
    }

    fn bare(round: u32, load: Load, over: u64) -> BareRun {
        BareRun { round, load, over_deadline: over, round_trip_ns: percentiles(5_000) }
    }

    const EVENT: Contender = Contender { wait: WaitMode::Event, release: ReleaseTimer::Margin };

    /// Three rounds of `event` and `spin` idle and busy: the spreads per cell, the bare
    /// transport last in each load, the aims judged on the medians.
    fn three_rounds() -> Repeated {
        // (load, wait, misses in rounds 1–3, round-trip p50)
        let table: [(Load, WaitMode, [u64; 3], u64); 4] = [
            (Load::Idle, WaitMode::Event, [3, 12, 5], 50_000),
            (Load::Idle, WaitMode::Spin, [9, 8, 30], 10_000),
            (Load::Busy, WaitMode::Event, [80, 84, 90], 45_000),
            (Load::Busy, WaitMode::Spin, [4_800, 5_400, 5_000], 16_000),
        ];
        let bare_misses =
            |load: Load, k: usize| if load == Load::Idle { [4, 10, 6][k] } else { [900, 2_000, 1_500][k] };
        let (mut runs, mut bares) = (Vec::new(), Vec::new());
        for (k, round) in (1..=3).enumerate() {
            for (load, wait, misses, p50) in table {
                runs.push(run(round, load, wait, misses[k], bare_misses(load, k), p50));
            }
            for load in [Load::Idle, Load::Busy] {
                bares.push(bare(round, load, bare_misses(load, k)));
            }
        }
        Repeated::new(3, 10_000, 500_000, EVENT, runs, bares)
    }

    #[test]
    fn each_cell_spreads_its_runs_and_sets_them_against_the_same_rounds_bare_transport() {
        let r = three_rounds();
        let labels: Vec<(&str, &str)> = r.cells.iter().map(|c| (c.label.as_str(), c.load.as_str())).collect();
        assert_eq!(
            labels,
            [
                ("event", "idle"),
                ("spin", "idle"),
                (BARE, "idle"),
                ("event", "busy"),
                ("spin", "busy"),
                (BARE, "busy")
            ]
        );
        let e = r.cell_of("event", Load::Idle).unwrap();
        // Misses 3, 12, 5; against the bare transport's 4, 10, 6 of the same rounds: −1, +2, −1.
        assert_eq!((e.misses.median, e.misses.worst), (5.0, 12.0));
        let b = e.beyond_bare.unwrap();
        assert_eq!((b.median, b.best, b.worst), (-1.0, -1.0, 2.0));
        assert_eq!(e.plant_misses.unwrap().median, 2.0, "3/2, 12/2, 5/2 rounded down");
        let bare = r.cell_of(BARE, Load::Busy).unwrap();
        assert_eq!((bare.misses.median, bare.beyond_bare), (1_500.0, None));
        assert_eq!(r.cell_of("spin", Load::Busy).unwrap().runs_with_stops, 3);
    }

    #[test]
    fn the_default_is_held_to_the_aims_on_the_medians() {
        let r = three_rounds();
        let verdicts: Vec<Option<bool>> = r.aims.iter().map(|a| a.met).collect();
        // Idle: median beyond the bare transport −1 ≤ 0; busy: 84 ≤ 1 500; then the medians
        // side by side (idle, busy) and, idle, spin misses less? No: event's median 5 < 9.
        assert_eq!(verdicts, [Some(true), Some(true), None, None]);
        assert!(r.aims[0].measured.starts_with("-1"), "{}", r.aims[0].measured);
        assert!(r.aims[2].measured.contains("50.0 µs against 5.0 µs (10.0×)"), "{}", r.aims[2].measured);
        // With spin as the default, idle: median beyond the bare transport 5 (9−4, 8−10, 30−6:
        // 5, −2, 24): not met; event misses least, at a higher median.
        let spin = Contender { wait: WaitMode::Spin, release: ReleaseTimer::Margin };
        let r = Repeated::new(3, 10_000, 500_000, spin, r.runs, r.bare);
        assert_eq!(r.aims[0].met, Some(false));
        assert_eq!(r.aims[1].met, Some(false), "busy: 5 000 against 1 500");
        let least: Vec<&str> =
            r.aims.iter().filter(|a| a.aim.contains("misses least")).map(|a| a.measured.as_str()).collect();
        assert_eq!(least.len(), 2);
        assert!(
            least[0].starts_with("event (median 5 misses against the default's 9), at a higher"),
            "{}",
            least[0]
        );
    }

    #[test]
    fn the_markdown_table_has_a_row_per_cell_and_the_verdicts() {
        let r = three_rounds();
        let md = r.markdown("companion latency --repeat 3", "2 CPUs");
        assert!(md.starts_with("3 interleaved round(s) of 10000 cycles"), "{md}");
        let rows: Vec<&str> =
            md.lines().filter(|l| l.starts_with("| ") && !l.starts_with("| wait")).collect();
        assert_eq!(rows.len(), 6);
        assert_eq!(rows[0], "| **event** (default) | idle | 5 [4–8.5] (12) | -1 [-1–+0.5] (+2) | 2 / 3 | 50.0 µs [50.0 µs–50.0 µs] (50.0 µs) | 500.0 µs [500.0 µs–500.0 µs] (500.0 µs) |");
        assert!(
            rows[2].starts_with("| bare iceoryx2 (paced, busy-poll) | idle | 6 [5–8] (10) | — | — |"),
            "{}",
            rows[2]
        );
        assert!(md.contains("— **met**"));
    }

    #[test]
    fn contenders_pair_each_mode_that_sleeps_to_the_release_with_each_timer() {
        let all = Contender::all(
            &[WaitMode::Adaptive, WaitMode::Spin, WaitMode::Event],
            &[ReleaseTimer::Margin, ReleaseTimer::Timerfd],
        );
        let labels: Vec<String> = all.iter().map(Contender::label).collect();
        assert_eq!(labels, ["adaptive", "adaptive+timerfd", "spin", "event", "event+timerfd"]);
        // No timer asked: each mode once.
        assert_eq!(Contender::all(&[WaitMode::Event, WaitMode::Hybrid], &[]).len(), 2);
    }

    #[test]
    fn the_box_plot_draws_a_box_per_cell() {
        let r = three_rounds();
        let dir = std::env::temp_dir().join(format!("companion-repeat-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("r.svg");
        r.plot(&p).unwrap();
        let svg = std::fs::read_to_string(&p).unwrap();
        for text in ["misses per run, idle", "round trip p99.9 per run, busy", BARE, "event", "spin"] {
            assert!(svg.contains(text), "{text}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
