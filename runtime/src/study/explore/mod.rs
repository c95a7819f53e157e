//! `companion explore`: Monte Carlo over initial conditions and controller parameters —
//! where does the law converge from, and with which parameters?
//!
//! The paper proves convergence only locally (Proposition 1) and suggests evaluating the
//! attraction domain "through extensive simulations"; this is that. Each sample is a full
//! closed-loop run without per-step files ([`crate::study::trial`]), classified (converged, not
//! converged, diverged, rejected) and described by its tracked fraction, settling time,
//! smallest joint margin, largest speed, time saturated and rejected steps.
//!
//! Output, in `--out DIR`:
//!
//! - `results.csv`: one line per sample, in sample order, each with a checksum
//!   ([`results`]);
//! - `summary.json`: counts, spreads, the success map's cells, the bound on `‖e_p‖` against
//!   the transverse function's size ([`summary`]);
//! - `map.svg`, `settling.svg`, `tracked.svg`, `margin.svg`, `ep_bound.svg`, `index.html`;
//! - `explore.json`: what was explored (scenario, space, samples, seed) and its hash.
//!
//! **Deterministic.** Sample `i`'s values are drawn from ChaCha12 stream `i` of the seed,
//! whatever thread runs it and whatever ran before; the files are written from the lines in
//! sample order. So the bytes are the same for any thread count, any shard split, any number
//! of interruptions.
//!
//! **Resumable.** Each finished sample is appended to `journal.csv` at once (one write of
//! one line). Run the same command again after a kill: the journal is verified line by line,
//! a last line cut short by the kill is dropped (that sample runs again), the samples in it
//! are not run again; a line that is complete but corrupt stops the run with an error
//! instead of being used.
//!
//! **Shardable.** `--shard K/N` runs the samples `i` with `i mod N = K − 1` into its own
//! folder; [`merge`] checks that the shards are of the same exploration, complete and
//! intact, and writes the same files an unsharded run writes.
//!
//! **One process per folder.** A run locks its folder ([`lock`]); a second run on the same
//! folder is refused at once with [`Busy`] (the CLI's exit code 9), and [`merge`] tells a
//! shard still running (locked) from one that ended unfinished (run its command again).

pub mod error;
pub mod lock;
mod plots;
pub mod results;
pub mod space;
pub mod summary;

use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::io::{Read as _, Seek as _, SeekFrom, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use companion_core::PlatformKind;
use rand::rngs::ChaCha12Rng;
use rand::{Rng as _, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

pub use self::error::{BadShard, ExploreError};
pub use self::lock::Busy;
use self::lock::Lock;
pub use self::results::{Class, Record};
pub use self::space::{Space, SpaceFile, Value};
pub use self::summary::ExploreSummary;
use crate::domain::observe::Observer;
use crate::domain::scenario::{Scenario, ScenarioBuilder};
use crate::study::knobs::Knob;
use crate::study::shared;
pub use crate::study::trial::SpatialSetup;
use crate::study::trial::{self, Figures, Tail, TrialError};

/// The result of an exploration's steps.
type Result<T, E = ExploreError> = std::result::Result<T, E>;

/// Which part of the samples a run takes: `K/N` takes the samples `i` with `i mod N = K − 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Shard {
    /// `K`, from 1.
    pub index: u64,
    /// `N ≥ 1`.
    pub count: u64,
}

impl Shard {
    /// All samples.
    pub const WHOLE: Shard = Shard { index: 1, count: 1 };

    /// Parses `K/N`.
    ///
    /// # Errors
    /// Not of the form `K/N` with `1 ≤ K ≤ N`.
    pub fn parse(text: &str) -> Result<Self, BadShard> {
        let bad = || BadShard(text.to_string());
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) =
            (k.trim().parse::<u64>().map_err(|_| bad())?, n.trim().parse::<u64>().map_err(|_| bad())?);
        if index == 0 || count == 0 || index > count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }

    /// Whether sample `i` is this shard's.
    pub fn owns(self, i: u64) -> bool {
        i % self.count == self.index - 1
    }

    /// This shard's samples among `0..samples`.
    pub fn samples(self, samples: u64) -> impl Iterator<Item = u64> {
        (self.index - 1..samples).step_by(usize::try_from(self.count).unwrap_or(usize::MAX))
    }
}

/// An exploration: the scenario every sample starts from, the space, how many samples.
#[derive(Clone, Debug)]
pub struct Exploration {
    /// Builds the base scenario (platform, trajectory, choice, limits, config, dt, duration).
    pub builder: ScenarioBuilder,
    /// The base scenario.
    pub base: Scenario,
    /// The checked space.
    pub space: Space,
    /// How many samples (indices `0..samples`).
    pub samples: u64,
    /// The seed.
    pub seed: u64,
    /// The spatial arm and target (`--arm`); `None`: the paper's planar arm.
    pub spatial: Option<SpatialSetup>,
}

/// What `explore.json` records: everything the samples depend on.
#[derive(Serialize)]
struct Identity<'a> {
    format: &'static str,
    samples: u64,
    seed: u64,
    scenario: &'a Scenario,
    #[serde(skip_serializing_if = "Option::is_none")]
    arm: Option<ArmIdentity>,
    space: &'a Space,
    columns: String,
}

/// A spatial exploration's arm and target in `explore.json`: the arm's name, joints and hash
/// (companion-core's chain, as the HIL handshake hashes it), the target.
#[derive(Serialize)]
struct ArmIdentity {
    name: String,
    joints: usize,
    hash: String,
    target: String,
}

/// `explore.json`: the identity and its hash (the same for every shard of an exploration;
/// a shard's folder has `shard.json` besides).
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    identity: Identity<'a>,
    hash: String,
}

/// How a run ended.
#[derive(Clone, Debug)]
pub struct ExploreOutcome {
    /// The summary (`None` if interrupted before every sample was done).
    pub summary: Option<ExploreSummary>,
    /// Samples found done in the journal (resumed).
    pub resumed: u64,
    /// Samples run now.
    pub ran: u64,
    /// Wall time of the samples run now (s).
    pub wall_s: f64,
    /// CPU time of the process while they ran (s), where the system tells it.
    pub cpu_s: Option<f64>,
    /// Closed-loop steps simulated now.
    pub steps: u64,
    /// A notice for the user (e.g. a cut line dropped).
    pub notes: Vec<String>,
}

/// The platform's transverse-function size, the variable the bound on `‖e_p‖` is shown against.
fn size_knob(platform: PlatformKind) -> Option<Knob> {
    match platform {
        PlatformKind::Car => Some(Knob::Epsilon),
        PlatformKind::Unicycle => Some(Knob::Epsilon1),
        PlatformKind::Omni => None,
    }
}

impl Exploration {
    /// An exploration of `space` around the scenario `builder` makes.
    ///
    /// # Errors
    /// The scenario or the space is invalid (see [`Space::check`]), or `samples` is 0.
    pub fn new(builder: ScenarioBuilder, file: &SpaceFile, samples: u64, seed: u64) -> Result<Self> {
        Self::with_arm(builder, None, file, samples, seed)
    }

    /// An exploration of `space` around the scenario `builder` makes, with the spatial arm
    /// and target of `spatial` if given (`builder` then carries the platform settings and
    /// flags of the run, as for `sim --arm`).
    ///
    /// # Errors
    /// As [`new`](Self::new); with an arm, a space or a run that spatial runs do not allow.
    pub fn with_arm(
        builder: ScenarioBuilder,
        spatial: Option<SpatialSetup>,
        file: &SpaceFile,
        samples: u64,
        seed: u64,
    ) -> Result<Self> {
        if samples == 0 {
            return Err(ExploreError::NoSamples);
        }
        let builder = if spatial.is_some() { builder.for_spatial_arm() } else { builder };
        let base = builder.clone().build().map_err(ExploreError::Scenario)?;
        let space = Space::check_for(file, &builder, spatial.as_ref())?;
        Ok(Self { builder, base, space, samples, seed, spatial })
    }

    /// The name of the runs explored (`traj1-a-car`, `ur5-traj2-a-unicycle`).
    fn name(&self) -> String {
        match &self.spatial {
            None => self.base.name.clone(),
            Some(setup) => crate::run::spatial::SpatialScenario::new(
                self.base.clone(),
                setup.arm.clone(),
                setup.target.clone(),
            )
            .map_or_else(|_| self.base.name.clone(), |s| s.name),
        }
    }

    fn arm_identity(&self) -> Option<ArmIdentity> {
        let setup = self.spatial.as_ref()?;
        let arm = &setup.arm;
        let hash = match arm.joints() {
            6 => arm.chain::<f64, 6>().map(|c| crate::transport::wire::canonical::arm_hash(&c)),
            7 => arm.chain::<f64, 7>().map(|c| crate::transport::wire::canonical::arm_hash(&c)),
            _ => arm.chain::<f64, 8>().map(|c| crate::transport::wire::canonical::arm_hash(&c)),
        };
        Some(ArmIdentity {
            name: arm.name().to_string(),
            joints: arm.joints(),
            hash: hash.map_or_else(|e| e.to_string(), |h| format!("{h:016x}")),
            target: match &setup.target {
                crate::run::spatial::SpatialTargetChoice::Lifted(t) => {
                    format!("lifted trajectory {}", crate::domain::scenario::trajectory_number(*t))
                }
                crate::run::spatial::SpatialTargetChoice::File(p) => p.display().to_string(),
            },
        })
    }

    fn knobs(&self) -> Vec<Knob> {
        results::knob_columns(&self.space, size_knob(self.base.controller.platform))
    }

    fn header(&self) -> String {
        results::header(&self.knobs())
    }

    fn identity(&self) -> Identity<'_> {
        Identity {
            format: "companion-explore/1",
            samples: self.samples,
            seed: self.seed,
            scenario: &self.base,
            arm: self.arm_identity(),
            space: &self.space,
            columns: self.header(),
        }
    }

    /// The hash of what the samples depend on (16 hex digits).
    pub fn hash(&self) -> Result<String> {
        Ok(format!("{:016x}", results::fnv1a(serde_json::to_string(&self.identity())?.as_bytes())))
    }

    fn manifest(&self) -> Result<String> {
        let m = Manifest { identity: self.identity(), hash: self.hash()? };
        Ok(serde_json::to_string_pretty(&m)? + "\n")
    }

    /// What writing the files needs.
    pub fn layout(&self) -> Layout {
        Layout {
            scenario: self.name(),
            seed: self.seed,
            samples: self.samples,
            space: self.space.clone(),
            knobs: self.knobs(),
            header: self.header(),
        }
    }

    /// The uniform draws of sample `i`: ChaCha12 stream `i` of the seed.
    pub fn draws(&self, i: u64) -> [f64; space::DRAWS] {
        let mut rng = ChaCha12Rng::seed_from_u64(self.seed);
        rng.set_stream(i);
        let mut u = [0.0; space::DRAWS];
        for x in &mut u {
            // 53 random bits: uniform on [0, 1).
            {
                *x = (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
            }
        }
        u
    }

    /// Runs sample `i`: its line of `results.csv` and the steps it simulated.
    pub fn run_sample(&self, i: u64) -> (String, u64) {
        let point = self.space.point(&self.draws(i));
        let knobs = self.knobs();
        let mut inputs: Vec<f64> = point.initial.to_vec();
        for k in &knobs {
            let v = point.parameters.iter().find(|(p, _)| p == k).map(|(_, v)| *v);
            inputs.push(v.unwrap_or_else(|| k.value(&self.base)));
        }
        let judge = self.space.judge;
        let ran: Option<(Figures, Tail)> = match &self.spatial {
            None => self
                .space
                .scenario(&self.builder, &self.base, &point)
                .map_err(TrialError::from)
                .and_then(|s| trial::run(&s, &judge))
                .ok()
                .map(|t| (t.figures(), t.tail)),
            Some(setup) => self
                .space
                .spatial_scenario(&self.builder, &self.base, setup, &point)
                .ok()
                .and_then(|s| trial::run_spatial(&s, &judge).ok())
                .map(|t| (t.figures(), t.tail)),
        };
        match ran {
            Some((f, tail)) => {
                (results::line(i, &inputs, Class::of(&f, &tail, &judge), Some((&f, &tail))), f.steps)
            }
            None => (results::line(i, &inputs, Class::Invalid, None), 0),
        }
    }

    /// Runs this shard's samples into `out` (resuming what a journal there holds), then writes
    /// the results. Stops early, with the journal kept, when `stop()` says so.
    ///
    /// # Errors
    /// Another process is running in `out` ([`Busy`], at once, before anything is read), `out`
    /// holds another exploration, its journal is corrupt, or a file cannot be written.
    pub fn run(
        &self,
        out: &Path,
        shard: Shard,
        observer: &dyn Observer,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<ExploreOutcome> {
        std::fs::create_dir_all(out).map_err(on_file("creating", out))?;
        let manifest = self.manifest()?;
        let shard_json = (shard != Shard::WHOLE)
            .then(|| serde_json::to_string_pretty(&ShardFile { index: shard.index, count: shard.count }))
            .transpose()?
            .map(|s| s + "\n");
        let mut notes = Vec::new();
        let manifest_path = out.join("explore.json");
        let shard_path = out.join("shard.json");
        // Locked before anything else is read, held until this function returns (`lock`).
        let mut manifest_file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&manifest_path)
            .map_err(on_file("opening", &manifest_path))?;
        match lock::try_lock(&manifest_file, true).map_err(on_file("locking", &manifest_path))? {
            Lock::Held => {}
            Lock::Busy => return Err(ExploreError::Busy(Busy { folder: out.to_path_buf() })),
            Lock::Unsupported => notes.push(format!(
                "{}'s file system does not support locks: nothing stops a second process on this folder",
                out.display()
            )),
        }
        let mut old = String::new();
        manifest_file.read_to_string(&mut old).map_err(on_file("reading", &manifest_path))?;
        // Empty: a new folder. A proper beginning of this manifest and nothing else in the
        // folder: a first run killed while writing it.
        let unwritten = old.is_empty()
            || (old.len() < manifest.len()
                && manifest.starts_with(&old)
                && !out.join("journal.csv").exists()
                && !out.join("results.csv").exists());
        if unwritten {
            let writing = output("writing explore.json");
            manifest_file.set_len(0).map_err(writing)?;
            manifest_file.seek(SeekFrom::Start(0)).map_err(writing)?;
            manifest_file.write_all(manifest.as_bytes()).map_err(writing)?;
            if let Some(sj) = &shard_json {
                std::fs::write(&shard_path, sj).map_err(output("writing shard.json"))?;
            }
        } else if old != manifest || std::fs::read_to_string(&shard_path).ok() != shard_json {
            return Err(ExploreError::Another { folder: out.to_path_buf() });
        }
        let layout = self.layout();
        let header = &layout.header;
        let mut done: BTreeMap<u64, String> = BTreeMap::new();
        // A finished run's results count as done (running the command again rewrites them).
        let results_path = out.join("results.csv");
        if results_path.exists() {
            let text = std::fs::read_to_string(&results_path)?;
            let (lines, cut) = results::read_lines(&text, header, "results.csv")?;
            if cut.is_some() {
                return Err(ExploreError::CutResults);
            }
            layout.take(&mut done, lines, shard, "results.csv")?;
        }
        let journal_path = out.join("journal.csv");
        if journal_path.exists() {
            let text = std::fs::read_to_string(&journal_path)?;
            let (lines, cut) = results::read_lines(&text, header, "journal.csv")?;
            if let Some(c) = cut {
                notes.push(format!(
                    "journal.csv ended in a line cut short by the kill ({} bytes dropped); that sample runs again",
                    c.len()
                ));
                let keep = (text.len() - c.len()) as u64;
                OpenOptions::new().write(true).open(&journal_path)?.set_len(keep)?;
            }
            layout.take(&mut done, lines, shard, "journal.csv")?;
        } else {
            std::fs::write(&journal_path, header.clone() + "\n").map_err(output("creating journal.csv"))?;
        }
        let resumed = done.len() as u64;
        let pending: Vec<u64> = shard.samples(self.samples).filter(|i| !done.contains_key(i)).collect();
        let journal = Mutex::new(OpenOptions::new().append(true).open(&journal_path)?);
        let finished = Mutex::new(Vec::with_capacity(pending.len()));
        let start = Instant::now();
        let cpu_start = crate::sys::machine::process_cpu_seconds();
        let steps = AtomicU64::new(0);
        pending.par_iter().try_for_each(|&i| -> Result<()> {
            if stop() {
                return Ok(());
            }
            let (line, n) = self.run_sample(i);
            steps.fetch_add(n, Ordering::Relaxed);
            {
                let mut f = shared::lock(&journal, "journal lock")?;
                f.write_all(format!("{line}\n").as_bytes()).map_err(output("appending to journal.csv"))?;
            }
            shared::lock(&finished, "lock")?.push((i, line));
            observer.advance(1);
            Ok(())
        })?;
        let wall_s = start.elapsed().as_secs_f64();
        let cpu_s = crate::sys::machine::process_cpu_seconds().zip(cpu_start).map(|(b, a)| b - a);
        let finished = shared::into_inner(finished)?;
        let ran = finished.len() as u64;
        done.extend(finished);
        let mut outcome =
            ExploreOutcome { summary: None, resumed, ran, wall_s, cpu_s, steps: steps.into_inner(), notes };
        if done.len() < shard.samples(self.samples).count() {
            return Ok(outcome);
        }
        outcome.summary = Some(layout.finish(out, &done)?);
        std::fs::remove_file(&journal_path).map_err(output("removing journal.csv"))?;
        Ok(outcome)
    }
}

/// What writing an exploration's files needs: its identity as `explore.json` records it.
#[derive(Clone, Debug)]
pub struct Layout {
    /// The base scenario's name.
    pub scenario: String,
    /// The seed.
    pub seed: u64,
    /// Samples.
    pub samples: u64,
    /// The space.
    pub space: Space,
    /// The knob columns.
    pub knobs: Vec<Knob>,
    /// The header of `results.csv`.
    pub header: String,
}

impl Layout {
    /// Adds verified lines to `done`: each must be this shard's and not differ from a line
    /// already there for the same sample.
    fn take(
        &self,
        done: &mut BTreeMap<u64, String>,
        lines: Vec<(u64, String)>,
        shard: Shard,
        what: &str,
    ) -> Result<()> {
        for (i, line) in lines {
            if i >= self.samples || !shard.owns(i) {
                return Err(ExploreError::NotThisRuns {
                    what: what.to_string(),
                    sample: i,
                    samples: self.samples,
                    index: shard.index,
                    count: shard.count,
                });
            }
            if let Some(old) = done.get(&i) {
                if *old != line {
                    return Err(ExploreError::Twice { what: what.to_string(), sample: i });
                }
            }
            done.insert(i, line);
        }
        Ok(())
    }

    /// Writes `results.csv` (atomically), `summary.json` and the figures from the lines in
    /// sample order.
    fn finish(&self, out: &Path, done: &BTreeMap<u64, String>) -> Result<ExploreSummary> {
        let header = &self.header;
        let mut text =
            String::with_capacity(done.values().map(|l| l.len() + 1).sum::<usize>() + header.len() + 1);
        text.push_str(header);
        text.push('\n');
        let columns = header.split(',').count();
        let mut records = Vec::with_capacity(done.len());
        for line in done.values() {
            text.push_str(line);
            text.push('\n');
            records.push(results::parse(line, columns)?);
        }
        let tmp = out.join("results.csv.tmp");
        std::fs::write(&tmp, &text).map_err(output("writing results.csv"))?;
        std::fs::rename(&tmp, out.join("results.csv")).map_err(output("writing results.csv"))?;
        let size = self.knobs.iter().copied().find(|k| matches!(k, Knob::Epsilon | Knob::Epsilon1));
        let summary = summary::summarize(&self.scenario, self.seed, &self.space, &self.knobs, size, &records);
        std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)? + "\n")
            .map_err(output("writing summary.json"))?;
        plots::render(out, &summary, &records, &self.knobs)?;
        Ok(summary)
    }
}

/// `explore.json` as read back.
#[derive(serde::Deserialize)]
struct ManifestIn {
    samples: u64,
    seed: u64,
    columns: String,
    space: Space,
    scenario: ScenarioHead,
}

#[derive(serde::Deserialize)]
struct ScenarioHead {
    name: String,
}

/// `shard.json` of a shard's folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
struct ShardFile {
    index: u64,
    count: u64,
}

/// Merges the shard folders `dirs` of one exploration into `out`: the same files an unsharded
/// run writes (byte for byte).
///
/// # Errors
/// A shard is still running (its lock is held), a folder is not a finished shard (the message
/// says whether to rerun it), the shards are of different explorations, shards are
/// missing or repeated, or a line is corrupt.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<ExploreSummary> {
    if dirs.is_empty() {
        return Err(ExploreError::NoShards);
    }
    let mut manifest: Option<String> = None;
    let mut count = None;
    let mut seen = BTreeMap::new();
    let mut done = BTreeMap::new();
    let mut layout: Option<Layout> = None;
    let mut held = Vec::with_capacity(dirs.len());
    for dir in dirs {
        let path = dir.join("explore.json");
        let mut file = std::fs::File::open(&path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                ExploreError::NotAnExploration { dir: dir.clone() }
            } else {
                on_file("reading", &path)(e)
            }
        })?;
        // Shared: a run's exclusive lock conflicts; held until the merge is written, so that no
        // run starts on a shard while it is read.
        if lock::try_lock(&file, false).map_err(on_file("locking", &path))? == Lock::Busy {
            return Err(ExploreError::Running { dir: dir.clone() });
        }
        let mut text = String::new();
        file.read_to_string(&mut text).map_err(on_file("reading", &path))?;
        held.push(file);
        match &manifest {
            None => {
                let m: ManifestIn = serde_json::from_str(&text)
                    .map_err(|source| ExploreError::Manifest { path: path.clone(), source })?;
                let knobs = m
                    .columns
                    .split(',')
                    .skip(1 + space::INITIAL.len())
                    .take_while(|c| *c != "class")
                    .map(|c| {
                        Knob::from_name(c).ok_or_else(|| ExploreError::UnknownColumn {
                            path: path.clone(),
                            column: c.to_string(),
                        })
                    })
                    .collect::<Result<Vec<_>>>()?;
                layout = Some(Layout {
                    scenario: m.scenario.name,
                    seed: m.seed,
                    samples: m.samples,
                    space: m.space,
                    knobs,
                    header: m.columns,
                });
                manifest = Some(text);
            }
            Some(first) if *first != text => {
                return Err(ExploreError::OtherExploration { dir: dir.clone(), first: dirs[0].clone() });
            }
            Some(_) => {}
        }
        let Some(layout) = &layout else { unreachable!() };
        let sp = dir.join("shard.json");
        let sf: ShardFile = serde_json::from_str(
            &std::fs::read_to_string(&sp)
                .map_err(|source| ExploreError::NotAShard { dir: dir.clone(), source })?,
        )
        .map_err(|source| ExploreError::ShardFile { path: sp.clone(), source })?;
        let shard = Shard { index: sf.index, count: sf.count };
        if shard.index == 0 || shard.index > shard.count {
            return Err(ExploreError::InvalidShard {
                dir: dir.clone(),
                index: shard.index,
                count: shard.count,
            });
        }
        if *count.get_or_insert(shard.count) != shard.count {
            return Err(ExploreError::Split {
                dir: dir.clone(),
                count: shard.count,
                others: count.unwrap_or(0),
            });
        }
        if let Some(other) = seen.insert(shard.index, dir.clone()) {
            return Err(ExploreError::ShardTwice {
                index: shard.index,
                count: shard.count,
                first: other,
                second: dir.clone(),
            });
        }
        let path = dir.join("results.csv");
        let what = path.display().to_string();
        let expected = shard.samples(layout.samples).count();
        let Ok(text) = std::fs::read_to_string(&path) else {
            // Not running (the lock was free): killed, failed or cancelled before the end.
            let journal = std::fs::read_to_string(dir.join("journal.csv")).unwrap_or_default();
            let in_journal = journal.lines().skip(1).filter(|l| !l.is_empty()).count();
            return Err(ExploreError::Unfinished {
                dir: dir.clone(),
                index: shard.index,
                count: shard.count,
                in_journal,
                expected,
            });
        };
        let (lines, cut) = results::read_lines(&text, &layout.header, &what)?;
        if cut.is_some() {
            return Err(ExploreError::CutShard { what });
        }
        let n = lines.len();
        layout.take(&mut done, lines, shard, &what)?;
        if n != expected {
            return Err(ExploreError::SampleCount {
                what,
                found: n,
                index: shard.index,
                count: shard.count,
                expected,
            });
        }
    }
    let (Some(layout), Some(manifest), Some(count)) = (layout, manifest, count) else { unreachable!() };
    let missing: Vec<String> =
        (1..=count).filter(|k| !seen.contains_key(k)).map(|k| format!("{k}/{count}")).collect();
    if !missing.is_empty() {
        return Err(ExploreError::Missing(missing));
    }
    std::fs::create_dir_all(out).map_err(on_file("creating", out))?;
    std::fs::write(out.join("explore.json"), manifest).map_err(output("writing explore.json"))?;
    let summary = layout.finish(out, &done)?;
    drop(held); // the shards' locks, held to here
    Ok(summary)
}

/// The error of `doing` (`creating`, `opening`, `locking`, `reading`) `path`.
fn on_file<'a>(doing: &'static str, path: &'a Path) -> impl FnOnce(std::io::Error) -> ExploreError + 'a {
    move |source| ExploreError::File { doing, path: path.to_path_buf(), source }
}

/// The error of `doing` a file of the output folder (`writing explore.json`, …).
fn output(doing: &'static str) -> impl Fn(std::io::Error) -> ExploreError + Copy {
    move |source| ExploreError::Output(doing, source)
}

#[cfg(test)]
mod tests;
