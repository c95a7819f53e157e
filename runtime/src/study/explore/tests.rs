//! Determinism across thread counts and shards, resuming after a kill, one process per
//! folder, corrupt files, and bad spaces refused before anything runs.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;

use super::*;
use crate::domain::observe::Silent;
use crate::domain::scenario::Scenario;

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("companion-explore-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn builder(platform: PlatformKind) -> ScenarioBuilder {
    Scenario::builder(PaperTrajectory::One, PaperRun::A, platform).duration(1.5)
}

fn space() -> SpaceFile {
    let mut f = SpaceFile::around_the_target();
    f.initial.distance = Some(Value::Range([1.5, 3.0]));
    f.initial.alpha_1 = Some(Value::Range([0.0, 6.0]));
    f.judge = Some(space::JudgeFile { window: Some(0.5), ..Default::default() });
    f
}

fn exploration(samples: u64) -> Exploration {
    Exploration::new(builder(PlatformKind::Car), &space(), samples, 7).unwrap()
}

fn never() -> bool {
    false
}

fn run_with_threads(e: &Exploration, out: &Path, shard: Shard, threads: usize) -> ExploreOutcome {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| e.run(out, shard, &Silent, &never)).unwrap()
}

fn read(d: &Path, f: &str) -> Vec<u8> {
    std::fs::read(d.join(f)).unwrap_or_else(|e| panic!("{}: {e}", d.join(f).display()))
}

const FILES: [&str; 4] = ["results.csv", "summary.json", "explore.json", "map.svg"];

#[test]
fn the_same_bytes_for_any_thread_count_and_any_shard_split() {
    let e = exploration(10);
    let (one, two) = (dir("t1"), dir("t2"));
    let a = run_with_threads(&e, &one, Shard::WHOLE, 1);
    run_with_threads(&e, &two, Shard::WHOLE, 2);
    let s = a.summary.unwrap();
    assert_eq!(s.samples, 10);
    for f in FILES {
        assert!(read(&one, f) == read(&two, f), "{f} differs between 1 and 2 threads");
    }
    // Three shards, in a different thread count each, merged.
    let shards: Vec<PathBuf> = (1..=3).map(|k| dir(&format!("s{k}"))).collect();
    for (k, d) in shards.iter().enumerate() {
        let shard = Shard { index: k as u64 + 1, count: 3 };
        let o = run_with_threads(&e, d, shard, 1 + k % 2);
        assert_eq!(o.summary.unwrap().samples, shard.samples(10).count() as u64);
    }
    let merged = dir("merged");
    // Given in any order.
    merge(&[shards[2].clone(), shards[0].clone(), shards[1].clone()], &merged).unwrap();
    for f in FILES {
        assert!(read(&one, f) == read(&merged, f), "{f} differs between the unsharded run and the merge");
    }
    // A missing shard, a repeated one, and a shard of another exploration are refused.
    let err = merge(&shards[..2], &dir("m2")).unwrap_err().to_string();
    assert!(err.contains("shards missing: 3/3"), "{err}");
    let err = merge(&[shards[0].clone(), shards[0].clone()], &dir("m3")).unwrap_err().to_string();
    assert!(err.contains("given twice"), "{err}");
    let other = Exploration::new(builder(PlatformKind::Car), &space(), 10, 8).unwrap();
    let od = dir("other");
    run_with_threads(&other, &od, Shard { index: 3, count: 3 }, 1);
    let err = merge(&[shards[0].clone(), shards[1].clone(), od], &dir("m4")).unwrap_err().to_string();
    assert!(err.contains("another exploration"), "{err}");
    // The unsharded folder is not a shard.
    let err = merge(std::slice::from_ref(&one), &dir("m5")).unwrap_err().to_string();
    assert!(err.contains("not a shard"), "{err}");
    // A corrupt line in a shard's results is detected, not merged.
    let path = shards[1].join("results.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[1] = lines[1].replacen(",0.", ",1.", 1);
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let err = merge(&shards, &dir("m6")).unwrap_err().to_string();
    assert!(err.contains("corrupt") && err.contains("line 2"), "{err}");
    for d in [one, two, merged].iter().chain(&shards) {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn a_killed_exploration_resumes_and_loses_nothing() {
    let e = exploration(8);
    let whole = dir("whole");
    run_with_threads(&e, &whole, Shard::WHOLE, 1);
    // Interrupted after three samples (as SIGINT does: the next ones are not started).
    let out = dir("resume");
    let started = AtomicUsize::new(0);
    let stop = || started.fetch_add(1, Ordering::SeqCst) >= 3;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let first = pool.install(|| e.run(&out, Shard::WHOLE, &Silent, &stop)).unwrap();
    assert!(first.summary.is_none());
    assert_eq!(first.ran, 3);
    assert!(!out.join("results.csv").exists());
    // A kill in the middle of a write leaves a cut line at the end of the journal.
    let journal = out.join("journal.csv");
    let text = std::fs::read_to_string(&journal).unwrap();
    assert_eq!(text.lines().count(), 4, "header and three samples");
    let cut = &text.lines().nth(1).unwrap()[..20];
    std::fs::write(&journal, format!("{text}{cut}")).unwrap();
    let second = run_with_threads(&e, &out, Shard::WHOLE, 2);
    assert_eq!((second.resumed, second.ran), (3, 5));
    assert!(second.notes.iter().any(|n| n.contains("cut short")), "{:?}", second.notes);
    for f in FILES {
        assert!(read(&whole, f) == read(&out, f), "{f} differs after resuming");
    }
    assert!(!journal.exists(), "the journal is removed once the results are written");
    // Running the finished command again runs nothing and rewrites the same files.
    let third = run_with_threads(&e, &out, Shard::WHOLE, 1);
    assert_eq!((third.resumed, third.ran), (8, 0));
    assert!(read(&whole, "results.csv") == read(&out, "results.csv"));
    // Another exploration into the same folder is refused.
    let other = exploration(9);
    let err = other.run(&out, Shard::WHOLE, &Silent, &never).unwrap_err().to_string();
    assert!(err.contains("another exploration"), "{err}");
    let _ = std::fs::remove_dir_all(&whole);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn a_second_process_on_a_folder_is_refused_and_merge_tells_running_from_unfinished() {
    let e = exploration(6);
    let shards: Vec<PathBuf> = (1..=2).map(|k| dir(&format!("lock{k}"))).collect();
    let (one, two) = (Shard { index: 1, count: 2 }, Shard { index: 2, count: 2 });
    run_with_threads(&e, &shards[1], two, 1);
    // Shard 1 stopped after two of its three samples; then "running" (its lock held, as the
    // process running it holds it; flock locks conflict between two opens in one process too).
    let started = AtomicUsize::new(0);
    let stop = || started.fetch_add(1, Ordering::SeqCst) >= 2;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    assert!(pool.install(|| e.run(&shards[0], one, &Silent, &stop)).unwrap().summary.is_none());
    let holder = std::fs::File::open(shards[0].join("explore.json")).unwrap();
    assert_eq!(lock::try_lock(&holder, true).unwrap(), Lock::Held);
    let journal = read(&shards[0], "journal.csv");
    let err = e.run(&shards[0], one, &Silent, &never).unwrap_err();
    assert!(matches!(&err, ExploreError::Busy(b) if *b == Busy { folder: shards[0].clone() }), "{err:#}");
    assert!(read(&shards[0], "journal.csv") == journal, "the refused run touched the journal");
    let err = merge(&shards, &dir("lock-m1")).unwrap_err().to_string();
    assert!(err.contains("still running"), "{err}");
    // The holder gone (killed): unfinished, not running, and how far it got.
    drop(holder);
    let err = merge(&shards, &dir("lock-m2")).unwrap_err().to_string();
    assert!(
        err.contains("shard 1/2 is unfinished and no process is running it (2 of its 3 samples"),
        "{err}"
    );
    assert_eq!(run_with_threads(&e, &shards[0], one, 1).ran, 1);
    let merged = dir("lock-m3");
    merge(&shards, &merged).unwrap();
    // A first run killed while writing explore.json: the folder is taken as new.
    let whole = dir("lock-whole");
    run_with_threads(&e, &whole, Shard::WHOLE, 1);
    let cut = dir("lock-cut");
    std::fs::create_dir_all(&cut).unwrap();
    std::fs::write(cut.join("explore.json"), &read(&whole, "explore.json")[..40]).unwrap();
    run_with_threads(&e, &cut, Shard::WHOLE, 1);
    for f in FILES {
        assert!(read(&whole, f) == read(&merged, f), "{f}: merge differs from the unsharded run");
        assert!(read(&whole, f) == read(&cut, f), "{f}: the run over a cut explore.json differs");
    }
    for d in shards.iter().chain([&merged, &whole, &cut]) {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn a_corrupt_journal_is_detected_not_used() {
    let e = exploration(4);
    let out = dir("corrupt");
    let stop_after = AtomicUsize::new(0);
    let stop = || stop_after.fetch_add(1, Ordering::SeqCst) >= 2;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| e.run(&out, Shard::WHOLE, &Silent, &stop)).unwrap();
    let journal = out.join("journal.csv");
    let text = std::fs::read_to_string(&journal).unwrap();
    // One digit changed in a complete line: its checksum no longer matches.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let k = lines[1].find(|c: char| c.is_ascii_digit() && c != '0').unwrap_or(0);
    let mut bytes = lines[1].clone().into_bytes();
    bytes[k] = if bytes[k] == b'9' { b'8' } else { bytes[k] + 1 };
    lines[1] = String::from_utf8(bytes).unwrap();
    std::fs::write(&journal, lines.join("\n") + "\n").unwrap();
    let err = e.run(&out, Shard::WHOLE, &Silent, &never).unwrap_err().to_string();
    assert!(err.contains("journal.csv, line 2: corrupt"), "{err}");
    assert!(!out.join("results.csv").exists());
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_spaces_are_refused_before_anything_runs() {
    let b = || builder(PlatformKind::Car);
    let check = |text: &str| -> String {
        let f: Result<SpaceFile, _> = toml::from_str(text);
        match f {
            Err(e) => e.to_string(),
            Ok(f) => Exploration::new(b(), &f, 10, 1)
                .map(|_| String::from("accepted"))
                .unwrap_or_else(|e| format!("{e:#}")),
        }
    };
    assert!(check("[initial]\ndistance = [3.0, 1.0]").contains("empty range"));
    assert!(check("[initial]\ndistance = [1.0, 1.0]").contains("empty range"));
    assert!(check("[initial]\ndistance = [1.0, inf]").contains("finite"));
    assert!(check("[initial]\nradius = [1.0, 2.0]").contains("unknown field `radius`"));
    assert!(check("[parameters]\nepsilonn = [0.1, 0.2]").contains("unknown parameter `epsilonn`"));
    assert!(check("[parameters]\nepsilon_1 = [0.1, 0.2]").contains("unicycle platform"));
    // Lemma 2 at a corner: η₁ large against η₂, η₃.
    let e = check("[parameters]\neta_1 = [1.0, 30.0]");
    assert!(e.contains("corner") && e.contains("Lemma 2"), "{e}");
    assert!(check("[parameters]\nepsilon = [-0.1, 0.2]").contains("epsilon"));
    assert!(check("[initial]\nq2 = [0.1, 0.8]").contains("strictly inside"));
    let e = check("[initial]\ndistance = 2.0\n[map]\nx = \"distance\"\ny = \"heading\"");
    assert!(e.contains("map axis `distance`"), "{e}");
    let e = check("[initial]\ndistance = 2.0\nbearing = 0.0\nheading = 0.0");
    assert!(e.contains("draws no variable"), "{e}");
    // One drawn variable: a one-row map over it.
    assert_eq!(check("[initial]\ndistance = 2.0\nbearing = 0.0\nheading = [0.0, 1.0]"), "accepted");
    let ranges = "[initial]\ndistance = [1.0, 2.0]\nheading = [0.0, 1.0]\n";
    assert!(check(&format!("{ranges}[judge]\nwindow = 100.0")).contains("judge.window"));
    assert!(check(&format!("{ranges}[map]\nx = \"distance\"\ny = \"distance\"")).contains("must differ"));
    assert!(Exploration::new(b(), &space(), 0, 1).unwrap_err().to_string().contains("--samples"));
    assert_eq!(check("[parameters]\nepsilon = [0.1, 0.3]\nstroke = [0.7, 1.2]"), "accepted");
    assert!(Shard::parse("0/3").is_err() && Shard::parse("4/3").is_err() && Shard::parse("x").is_err());
    assert_eq!(Shard::parse("2/3").unwrap(), Shard { index: 2, count: 3 });
}

#[test]
fn a_sample_with_a_rejected_step_is_rejected_never_converged() {
    let s = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
        .duration(1.0)
        .build()
        .unwrap();
    let judge = crate::study::trial::Judge { window: 0.5, ..Default::default() };
    let t = crate::study::trial::run(&s, &judge).unwrap();
    let (mut f, mut tail) = (t.figures(), t.tail);
    tail.window_max_ep = 0.0;
    assert_eq!(Class::of(&f, &tail, &judge), Class::Converged);
    f.rejected_steps = 1;
    assert!(!tail.converged(f.rejected_steps, &judge));
    assert_eq!(Class::of(&f, &tail, &judge), Class::Rejected);
    tail.diverged_at = Some(0.5);
    assert_eq!(Class::of(&f, &tail, &judge), Class::Rejected);
    f.rejected_steps = 0;
    assert_eq!(Class::of(&f, &tail, &judge), Class::Diverged);
}

/// A spatial exploration (`--arm`): the UR5 on the unicycle, 2 s, α(0) and the joint speeds
/// drawn.
fn spatial(samples: u64, file: &SpaceFile) -> Result<Exploration> {
    use crate::domain::arm::SpatialArmSpec;
    use crate::run::spatial::SpatialTargetChoice;
    let b = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle).duration(2.0);
    let setup =
        SpatialSetup { arm: SpatialArmSpec::Ur5, target: SpatialTargetChoice::Lifted(PaperTrajectory::One) };
    Exploration::with_arm(b, Some(setup), file, samples, 3)
}

fn spatial_space(text: &str) -> SpaceFile {
    toml::from_str(text).unwrap()
}

/// With a spatial arm each sample is `sim --arm`'s run: at the arm's own speeds and size the
/// trial's figures are the spatial run's summary (same final ‖e_p‖, margin, steps); the
/// files are the same bytes for any thread count and shard split; the joint speeds change
/// the run (a slower arm is held back by its guard).
#[test]
fn a_spatial_exploration_runs_sim_arms_runs_deterministically() {
    let file = spatial_space(
        "[initial]\nalpha_1 = [0.0, 0.5]\n[parameters]\njoint_speed = [0.2, 1.0]\nreach = 1.0\n[judge]\nwindow = 0.5",
    );
    let e = spatial(4, &file).unwrap();
    let (one, two) = (dir("sp1"), dir("sp2"));
    let s = run_with_threads(&e, &one, Shard::WHOLE, 1).summary.unwrap();
    assert_eq!(s.scenario, "ur5-traj1-a-unicycle");
    run_with_threads(&e, &two, Shard::WHOLE, 2);
    for f in FILES {
        assert!(read(&one, f) == read(&two, f), "{f} differs between 1 and 2 threads");
    }
    let text = String::from_utf8(read(&one, "results.csv")).unwrap();
    let header = text.lines().next().unwrap();
    assert!(header.contains(",joint_speed,reach,class,"), "{header}");
    let lines: Vec<Record> =
        text.lines().skip(1).map(|l| results::parse(l, header.split(',').count()).unwrap()).collect();
    assert_eq!(lines.len(), 4);
    for r in &lines {
        assert!(r.inputs[0].is_nan(), "no planar start: distance is NaN");
        assert!(r.outcome("maneuvers") >= 0.0, "counted for spatial runs as for planar ones");
        assert_ne!(r.class, Class::Invalid);
    }
    let manifest = String::from_utf8(read(&one, "explore.json")).unwrap();
    assert!(manifest.contains("\"arm\": {") && manifest.contains("\"name\": \"ur5\""), "{manifest}");
    // The same point as `sim --arm` runs it: the trial's figures are its summary's.
    use crate::domain::observe::Silent as Quiet;
    use crate::run::spatial::run_spatial;
    let point = e.space.point(&e.draws(0));
    let setup = e.spatial.as_ref().unwrap();
    let sc = e.space.spatial_scenario(&e.builder, &e.base, setup, &point).unwrap();
    let t = crate::study::trial::run_spatial(&sc, &e.space.judge).unwrap();
    let d = dir("sp-sim");
    let (o, _) = run_spatial(&sc, &d, &Quiet, 0.01, None).unwrap();
    assert_eq!(t.summary.final_ep_norm, o.summary.final_ep_norm);
    assert_eq!(t.summary.min_joint_margin, o.summary.min_joint_margin);
    assert_eq!(t.summary.trajectory_digest, o.summary.trajectory_digest);
    assert_eq!(t.summary.steps, 2001);
    // The knob reaches the arm: at the published speeds the run is the preset's, bit for bit;
    // at a fifth of them the guard holds the arm back and the run differs.
    let at = |speed: f64| {
        let mut p = point.clone();
        p.parameters = vec![(Knob::JointSpeed, speed), (Knob::Reach, 1.0)];
        let sc = e.space.spatial_scenario(&e.builder, &e.base, setup, &p).unwrap();
        crate::study::trial::run_spatial(&sc, &e.space.judge).unwrap().summary
    };
    let (published, slow) = (at(1.0), at(0.2));
    let mut own = sc.clone();
    own.arm = crate::domain::arm::SpatialArmSpec::Ur5;
    let preset = crate::study::trial::run_spatial(&own, &e.space.judge).unwrap().summary;
    assert_eq!(published.trajectory_digest, preset.trajectory_digest);
    assert_ne!(slow.trajectory_digest, published.trajectory_digest);
    assert!(slow.max_joint_scale > 1.0, "{slow:?}");
    for d in [one, two, d] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// With a spatial arm: no planar start, no planar arm's knob, no arm scale the chain refuses,
/// and the arm's knobs not without one.
#[test]
fn bad_spatial_spaces_are_refused_before_anything_runs() {
    let check = |text: &str| {
        spatial(2, &spatial_space(text)).map_or_else(|e| format!("{e:#}"), |_| "accepted".into())
    };
    assert_eq!(check("[parameters]\njoint_speed = [0.5, 2.0]\nreach = [0.8, 1.2]"), "accepted");
    assert_eq!(check("[initial]\nalpha_2 = [0.0, 1.0]"), "accepted");
    let e = check("[initial]\ndistance = [1.0, 2.0]");
    assert!(e.contains("`distance` is not available with a spatial arm"), "{e}");
    let e = check("[parameters]\ngain = [1.0, 2.0]");
    assert!(e.contains("`gain` is a parameter of the paper's planar arm"), "{e}");
    let e = check("[parameters]\nstroke = [0.3, 0.5]");
    assert!(e.contains("`stroke` is a parameter of the paper's planar arm"), "{e}");
    assert_eq!(check("[parameters]\nlambda = [1.0, 2.0]"), "accepted");
    let e = check("[parameters]\njoint_speed = [0.0, 2.0]");
    let says = ["corner", "joint_speed = 0", "must be finite and > 0"];
    assert!(says.iter().all(|w| e.contains(w)), "{e}");
    let e = check("[parameters]\nepsilon = [0.1, 0.2]");
    assert!(e.contains("car"), "{e}");
    let planar = spatial_space("[parameters]\nreach = [0.5, 1.0]");
    let e = Exploration::new(builder(PlatformKind::Unicycle), &planar, 2, 1).unwrap_err().to_string();
    assert!(e.contains("`reach` is a parameter of a spatial arm"), "{e}");
    let planar = spatial_space("[parameters]\ndamping_below = [1e-3, 2e-2]");
    let e = Exploration::new(builder(PlatformKind::Unicycle), &planar, 2, 1).unwrap_err().to_string();
    assert!(e.contains("`damping_below` is a parameter of a spatial arm"), "{e}");
}

/// `damping_below` reaches a spatial arm's law: the point's scenario carries it, and a box
/// whose corner leaves `[0, 1)` is refused naming it.
#[test]
fn the_damping_onset_is_a_spatial_knob() {
    let e = spatial(2, &spatial_space("[parameters]\ndamping_below = [1e-3, 2e-2]")).unwrap();
    let setup = e.spatial.as_ref().unwrap();
    let mut point = e.space.point(&e.draws(0));
    point.parameters = vec![(Knob::DampingBelow, 0.02)];
    let sc = e.space.spatial_scenario(&e.builder, &e.base, setup, &point).unwrap();
    assert_eq!(sc.base.controller.overrides.damping_below, Some(0.02));
    assert_eq!(Knob::DampingBelow.value(&sc.base), 0.02);
    assert_eq!(Knob::DampingBelow.value(&e.base), companion_core::DAMPING_BELOW);
    let e = spatial(2, &spatial_space("[parameters]\ndamping_below = [1e-3, 1.5]")).map(|_| ()).unwrap_err();
    let e = format!("{e:#}");
    assert!(e.contains("corner") && e.contains("damping_below"), "{e}");
}
