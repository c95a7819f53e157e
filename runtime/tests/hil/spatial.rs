//! The HIL demo with a spatial arm (`--arm ur5|panda|FILE`, §5): lockstep runs byte-identical
//! to `companion sim --arm` (with `--delay` too), a real-time run that tracks, a chaos soak
//! whose counts match what was injected, and arms that do not match refused by both sides
//! with the reason.

use super::*;

/// The workspace's `examples/arms/NAME`.
fn arm_file(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/arms").join(name).display().to_string()
}

#[test]
fn a_spatial_arm_in_lockstep_is_byte_identical_to_sim() {
    let _g = serial();
    let panda = arm_file("panda.toml");
    // With a simulated delay the plant announces it and the controller predicts over it (or,
    // with --no-delay-compensation, over 0), as `companion sim --arm … --delay` does.
    let runs: [&[&str]; 5] = [
        &["--arm", "ur5"],
        &["--arm", "ur5", "--platform", "omni", "--trajectory", "2"],
        &["--arm", &panda, "--platform", "car", "--scalar", "f32", "--choice", "c"],
        &["--arm", "ur5", "--delay", "0.0025"],
        &["--arm", "panda", "--delay", "0.0025", "--no-delay-compensation"],
    ];
    for extra in runs {
        let (hs, _) = lockstep_equals_sim("2", extra);
        assert_eq!(hs["verdict"], "ok", "{extra:?}");
    }
}

#[test]
fn a_spatial_arm_in_real_time_tracks_its_target() {
    let _g = serial();
    let d = dir("spatial-rt");
    let n = name("spatial-rt");
    let out = d.to_str().unwrap();
    let args =
        relaxed(&["hil", "--arm", "ur5", "--duration", "4", "--log-every", "1", "--name", &n, "--out", out]);
    let (st, out, err) = run(&args);
    assert!(st.success(), "{out}\n{err}");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["mode"], "real-time");
    assert_eq!(lat["cycles"], 4001);
    assert_eq!(lat["stop_events"], 0);
    let s = json(&d.join("summary.json"));
    assert_eq!(s["verdict"], "ok", "{s:#}");
    assert_eq!(s["arm"], "ur5");
    assert_eq!(s["steps"], 4001);
    // The commands reached the arm: ‖e_p‖ (six components, from the plant's exact state) fell
    // to a fraction of where it started, and no joint came near a limit.
    let text = std::fs::read_to_string(d.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|c| *c == "ep_norm").unwrap();
    assert_eq!(header.last(), Some(&"status"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let ep: Vec<f64> = rows.iter().map(|r| r[col].parse().unwrap()).collect();
    assert_eq!(ep.len(), 4001, "every step");
    // Each period's command is the fresh answer or, after a missed deadline, the held one: the
    // rows say which, as many as the plant counted.
    let held = rows.iter().filter(|r| *r.last().unwrap() == "held").count();
    assert!(rows.iter().all(|r| matches!(*r.last().unwrap(), "ok" | "held")), "only fresh and held commands");
    assert_eq!(held as u64, lat["held_periods"].as_u64().unwrap());
    // summary.json says where the commands came from, as the planar arm's does.
    let sources = &s["command_sources"];
    assert_eq!(
        (sources["held"].as_u64(), sources["stopped"].as_u64()),
        (Some(held as u64), Some(0)),
        "{s:#}"
    );
    assert_eq!(sources["fresh"].as_u64(), Some(4001 - held as u64), "{s:#}");
    let (first, last) = (ep[0], ep[ep.len() - 1]);
    println!("‖e_p‖ {first:.3e} → {last:.3e}; {held} periods held");
    assert!(last < 0.25 * first, "‖e_p‖ {first} → {last}");
    assert!(s["smallest_joint_margin"].as_f64().unwrap() > 0.1, "{s:#}");
    // The floor clear of holds is reported beside the maximum; a 4 s run has no step after 20 s.
    assert_eq!(s["max_ep_norm_after_20s_clear_of_holds"], serde_json::Value::Null, "{s:#}");
    assert_eq!(s["steps_after_20s_clear_of_holds"], 0, "{s:#}");
    for f in ["top.svg", "side.svg", "latency.svg", "index.html"] {
        assert!(d.join(f).exists(), "{f}");
    }
}

#[test]
fn an_arm_file_equal_to_the_preset_is_admitted_and_another_arm_is_refused() {
    let _g = serial();
    // The file form of the UR5 is the preset, field for field: the same arm hash.
    let d = dir("arm-file");
    let n = name("arm-file");
    let ur5 = arm_file("ur5.toml");
    let plant = [&["--arm", "ur5"][..], &lockstep_plant(&n, &d)].concat();
    let ((ps, pe), (cs, ce)) = two_roles(&plant, &["--arm", &ur5, "--name", &n]);
    assert!(ps.success() && cs.success(), "plant:\n{pe}\ncontroller:\n{ce}");
    // The same joints, another limit: refused for the arm, both sides naming both arms.
    let other = d.join("ur5-other.toml");
    let text = std::fs::read_to_string(&ur5).unwrap();
    let changed = text.replacen("name = \"ur5-file\"", "name = \"ur5-narrow\"", 1).replacen(
        "limits = [-6.283185307179586, 6.283185307179586]",
        "limits = [-3.0, 3.0]",
        1,
    );
    assert_ne!(changed, text.replacen("name = \"ur5-file\"", "name = \"ur5-narrow\"", 1), "a limit changed");
    std::fs::write(&other, changed).unwrap();
    let refused = |plant: &[&str], control: &[&str], why: &str| {
        let d = dir("arm-refused");
        let n = name("arm-refused");
        let p = [&lockstep_plant(&n, &d)[..], plant].concat();
        let mut c = vec!["--name", n.as_str()];
        c.extend(control);
        let (plant, control) = two_roles(&p, &c);
        refused_for(&d, &plant, &control, why);
        (plant.1, control.1)
    };
    let (_, ce) = refused(&["--arm", "ur5"], &["--arm", other.to_str().unwrap()], "arm mismatch");
    assert!(ce.contains("the plant's arm is ur5"), "{ce}");
    refused(
        &["--arm", "ur5"],
        &["--arm", "panda"],
        "joint count mismatch: the plant has 6 joints, the controller is built for 7",
    );
    refused(
        &["--arm", "ur5"],
        &[],
        "joint count mismatch: the plant has 6 joints, the controller is built for 3",
    );
}

#[test]
fn a_killed_spatial_plant_leaves_its_rows_on_disk() {
    let _g = serial();
    let (demo, _, d) = kill_the_plant("spatial-kill", &["--arm", "ur5"]);
    let (st, seen) = demo.wait(Duration::from_secs(20));
    assert_eq!(st.code(), Some(3), "{seen:#?}");
    // The rows written as the run went (every 50 ms) are there, every line complete.
    rows_kept_after_the_kill(&d);
}

/// `--chaos` with a spatial arm, as with the paper's (the CI's soak): seeded stops of either
/// process, corrupted and held-back commands; the plant counts them, and the check in
/// `chaos.json` finds every count matching what was injected and every row on disk.
#[test]
fn a_spatial_chaos_soak_counts_what_was_injected() {
    let _g = serial();
    let d = dir("spatial-chaos");
    let n = name("spatial-chaos");
    let args =
        ["hil", "--arm", "ur5", "--chaos", "1", "--duration", "6", "--no-plots", "--quiet", "--name", &n];
    let mut all = args.to_vec();
    all.extend(["--out", d.to_str().unwrap()]);
    let (st, out, err) = run(&all);
    let chaos = json(&d.join("chaos.json"));
    assert!(st.success(), "{out}\n{err}\n{chaos:#}");
    assert_eq!(chaos["mismatches"], serde_json::json!([]), "{chaos:#}");
    let injected = &chaos["injected"];
    let corrupted: u64 = ["version", "session", "future_seq", "non_finite"]
        .iter()
        .map(|k| injected[k].as_u64().unwrap())
        .sum();
    assert!(corrupted > 0 && injected["delayed"].as_u64().unwrap() > 0, "{chaos:#}");
    assert_eq!(chaos["rows"][0], chaos["rows"][1], "every row on disk: {chaos:#}");
    assert_eq!(json(&d.join("summary.json"))["arm"], "ur5");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["invalid_total"].as_u64(), Some(corrupted), "{lat:#}");
}
