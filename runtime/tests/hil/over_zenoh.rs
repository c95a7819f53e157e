//! The HIL demo over Zenoh (cargo feature `zenoh`): lockstep determinism, a peer killed, a
//! partition, and bad endpoints — the same exit codes and reports as over iceoryx2. Faults
//! across a network are injected by a forwarding proxy on loopback ([`proxy`]); the tests
//! start and stop everything they use.

#[path = "over_zenoh/proxy.rs"]
mod proxy;

use std::net::TcpListener;

use self::proxy::Proxy;
use super::*;

/// A local TCP endpoint nobody listens on (a port that was free a moment ago).
fn free_endpoint() -> String {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    format!("tcp/127.0.0.1:{}", l.local_addr().unwrap().port())
}

fn port_of(ep: &str) -> u16 {
    ep.rsplit(':').next().unwrap().parse().unwrap()
}

fn spawn(args: &[&str]) -> Demo {
    Demo::start(args)
}

#[test]
fn lockstep_over_zenoh_is_byte_identical_to_sim() {
    let _g = serial();
    let runs: [&[&str]; 2] = [&[], &["--delay", "0.0025", "--platform", "car", "--choice", "d"]];
    for extra in runs {
        let d = dir("zenoh-lockstep");
        let (hil_dir, two_dir, sim_dir) = (d.join("hil"), d.join("two"), d.join("sim"));
        let n = name("zlock");
        // One command (`hil` picks a free local port) ...
        let mut args = vec!["hil", "--transport", "zenoh", "--lockstep", "--duration", "3", "--no-plots"];
        let hd = hil_dir.to_str().unwrap();
        args.extend(["--name", &n, "--out", hd]);
        args.extend(extra);
        let (st, out, err) = run(&args);
        assert!(st.success(), "{out}\n{err}");
        // ... and two, the controller connecting before the plant listens.
        let ep = free_endpoint();
        let td = two_dir.to_str().unwrap();
        let mut common =
            vec!["--transport", "zenoh", "--lockstep", "--duration", "3", "--no-plots", "--name", &n];
        common.extend(extra);
        let mut control = common.clone();
        control.extend(["--connect", &ep]);
        let mut plant = common.clone();
        plant.extend(["--listen", &ep, "--out", td]);
        let c = companion(&[&["control"], &control[..]].concat()).stderr(Stdio::piped()).spawn().unwrap();
        std::thread::sleep(Duration::from_millis(300));
        let (pst, perr) = {
            let o = companion(&[&["plant"], &plant[..]].concat()).output().unwrap();
            (o.status, String::from_utf8_lossy(&o.stderr).into_owned())
        };
        let co = c.wait_with_output().unwrap();
        assert!(pst.success(), "{perr}");
        assert!(co.status.success(), "{}", String::from_utf8_lossy(&co.stderr));
        let sd = sim_dir.to_str().unwrap();
        let mut args = vec!["sim", "--duration", "3", "--no-plots", "--out", sd];
        args.extend(extra);
        let (st, _, err) = run(&args);
        assert!(st.success(), "{err}");
        let s = std::fs::read(sim_dir.join("timeseries.csv")).unwrap();
        assert!(s.len() > 10_000, "a real file ({} bytes)", s.len());
        for dir in [&hil_dir, &two_dir] {
            let a = std::fs::read(dir.join("timeseries.csv")).unwrap();
            assert!(a == s, "{} over zenoh {extra:?} and sim differ", dir.display());
            let lat = json(&dir.join("latency.json"));
            assert_eq!(lat["mode"], "lockstep");
            assert_eq!(lat["cycles"], 3001);
            assert_eq!(lat["invalid_total"], 0);
        }
    }
}

#[test]
fn a_real_time_run_over_zenoh_succeeds_and_malformed_commands_are_dropped() {
    let _g = serial();
    let d = dir("zenoh-rt");
    let n = name("zrt");
    let (st, out, err) = run(&[
        "hil",
        "--transport",
        "zenoh",
        "--duration",
        "2",
        "--no-plots",
        "--hold-periods",
        LOADED_HOLD,
        "--max-miss-fraction",
        "1",
        "--inject",
        "version@100,nan@200,seq@300,session@400",
        "--name",
        &n,
        "--out",
        d.to_str().unwrap(),
    ]);
    assert!(st.success(), "{out}\n{err}");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["cycles"], 2001);
    assert_eq!(lat["invalid_total"], 4, "{lat:#}");
    let statuses = csv_statuses(&d.join("timeseries.csv"));
    assert!(statuses.len() > 150, "{} rows", statuses.len());
}

#[test]
fn killed_plant_over_zenoh_is_reported_like_over_iceoryx2() {
    let _g = serial();
    let d = dir("zenoh-kill-plant");
    let n = name("zkillp");
    let mut demo = spawn(&[
        "hil",
        "--transport",
        "zenoh",
        "--duration",
        "20",
        "--log-every",
        "1",
        "--hold-periods",
        LOADED_HOLD,
        "--max-miss-fraction",
        "1",
        "--no-plots",
        "--quiet",
        "--name",
        &n,
        "--out",
        d.to_str().unwrap(),
    ]);
    let pid = demo.plant_pid();
    std::thread::sleep(Duration::from_millis(1500));
    signal(pid, "KILL");
    let killed = Instant::now();
    let (noticed, line) = demo.wait_line("died", Duration::from_secs(10));
    println!("controller noticed the killed plant after {:?}: {line}", noticed.duration_since(killed));
    let (st, seen) = demo.wait(Duration::from_secs(20));
    assert_eq!(st.code(), Some(3), "{seen:#?}");
    assert!(seen.iter().any(|l| l.contains("killed by signal 9")), "{seen:#?}");
    let statuses = csv_statuses(&d.join("timeseries.csv"));
    assert!(statuses.len() > 500, "{} rows", statuses.len());
    let fault = json(&d.join("fault.json"));
    assert_eq!(fault["plant_exit"], "killed by signal 9");
    assert_eq!(fault["rows_on_disk"].as_u64(), Some(statuses.len() as u64));
}

/// Waits for `pid` to exit (at most 20 s).
fn wait_gone(pid: u32) {
    let end = Instant::now() + Duration::from_secs(20);
    while alive(pid) {
        assert!(Instant::now() < end, "process {pid} is still running");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// After the last fresh command: at most `hold` held periods, then stopped to the end.
fn held_then_stopped(statuses: &[String], hold: usize) {
    let last_ok = statuses.iter().rposition(|s| s != "held" && s != "stopped").expect("some fresh commands");
    let tail = &statuses[last_ok + 1..];
    let held = tail.iter().take_while(|s| *s == "held").count();
    assert!(held <= hold, "{tail:?}");
    assert!(!tail[held..].is_empty() && tail[held..].iter().all(|s| s == "stopped"), "{tail:?}");
}

#[test]
fn killed_controller_over_zenoh_makes_the_plant_stop_the_robot_and_exit_cleanly() {
    let _g = serial();
    let d = dir("zenoh-kill-controller");
    let n = name("zkillc");
    let mut demo = spawn(&[
        "hil",
        "--transport",
        "zenoh",
        "--duration",
        "20",
        "--log-every",
        "1",
        "--hold-periods",
        "5",
        "--no-plots",
        "--quiet",
        "--name",
        &n,
        "--out",
        d.to_str().unwrap(),
    ]);
    let plant = demo.plant_pid();
    std::thread::sleep(Duration::from_millis(1500));
    demo.child.kill().unwrap();
    let _ = demo.child.wait();
    wait_gone(plant);
    let lat = json(&d.join("latency.json"));
    let reason = lat["end"].as_str().unwrap();
    assert!(reason.contains("died") && reason.contains("robot stopped"), "{reason}");
    held_then_stopped(&csv_statuses(&d.join("timeseries.csv")), 5);
}

/// `companion plant` listening on a free port and `companion control` connecting through a
/// proxy that delays each direction by `delay`; both started, their stderr on channels.
fn through_proxy(tag: &str, delay: Duration, extra: &[&str]) -> (Proxy, Demo, Demo, PathBuf) {
    let d = dir(tag);
    let n = name(tag);
    let ep = free_endpoint();
    let upstream = format!("127.0.0.1:{}", port_of(&ep)).parse().unwrap();
    let proxy = Proxy::start(upstream, delay);
    let pe = proxy.endpoint();
    let out = d.to_str().unwrap();
    let mut common = vec!["--transport", "zenoh", "--no-plots", "--quiet", "--log-every", "1", "--name", &n];
    common.extend(extra);
    let plant = spawn(&[&["plant", "--listen", &ep, "--out", out], &common[..]].concat());
    let control = spawn(&[&["control", "--connect", &pe], &common[..]].concat());
    (proxy, plant, control, d)
}

#[test]
fn a_partition_is_a_dead_peer_hold_stop_report_clean_exit_codes() {
    let _g = serial();
    // The network cut (connections closed): both sides find the peer gone at once.
    let (proxy, plant, control, d) =
        through_proxy("zenoh-cut", Duration::ZERO, &["--duration", "20", "--hold-periods", "5"]);
    std::thread::sleep(Duration::from_millis(2500));
    proxy.cut();
    let (cst, cseen) = control.wait(Duration::from_secs(20));
    let (pst, pseen) = plant.wait(Duration::from_secs(20));
    assert_eq!(cst.code(), Some(3), "controller: {cseen:#?}");
    assert_eq!(pst.code(), Some(3), "plant: {pseen:#?}");
    assert!(cseen.iter().any(|l| l.contains("died")), "{cseen:#?}");
    let lat = json(&d.join("latency.json"));
    let reason = lat["end"].as_str().unwrap();
    assert!(reason.contains("robot stopped"), "{reason}");
    held_then_stopped(&csv_statuses(&d.join("timeseries.csv")), 5);
    drop(proxy);
    // A silent network (connections kept, nothing forwarded): the peer is alive but silent,
    // hung after --peer-timeout.
    let (proxy, plant, control, d) = through_proxy(
        "zenoh-stall",
        Duration::ZERO,
        &["--duration", "20", "--hold-periods", "5", "--peer-timeout", "1"],
    );
    std::thread::sleep(Duration::from_millis(2500));
    proxy.stall();
    let (cst, cseen) = control.wait(Duration::from_secs(20));
    let (pst, pseen) = plant.wait(Duration::from_secs(20));
    assert_eq!(cst.code(), Some(4), "controller: {cseen:#?}");
    assert_eq!(pst.code(), Some(4), "plant: {pseen:#?}");
    held_then_stopped(&csv_statuses(&d.join("timeseries.csv")), 5);
}

#[test]
fn bad_endpoints_are_clear_errors() {
    let _g = serial();
    // Malformed.
    for (role, flag, bad) in
        [("plant", "--listen", "localhost:7447"), ("control", "--connect", "tcp/host:port")]
    {
        let (st, _, err) = run(&[role, "--transport", "zenoh", flag, bad, "--duration", "1"]);
        assert_eq!(st.code(), Some(2), "{err}");
        assert!(err.contains("tcp/HOST:PORT") && err.contains(bad), "{err}");
    }
    let (st, _, err) = run(&["plant", "--transport", "zenoh", "--duration", "1"]);
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(err.contains("--listen"), "{err}");
    let (st, _, err) = run(&["plant", "--listen", "tcp/127.0.0.1:7447", "--duration", "1"]);
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(err.contains("--transport zenoh"), "{err}");
    // The port is taken.
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let ep = format!("tcp/127.0.0.1:{}", taken.local_addr().unwrap().port());
    let d = dir("zenoh-taken");
    let (st, _, err) = run(&[
        "plant",
        "--transport",
        "zenoh",
        "--listen",
        &ep,
        "--duration",
        "1",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(err.contains("cannot listen on") && err.contains(&ep), "{err}");
    drop(taken);
    // Nobody listens: an error naming the endpoint within the startup timeout.
    let ep = free_endpoint();
    let t0 = Instant::now();
    let (st, _, err) = run(&[
        "control",
        "--transport",
        "zenoh",
        "--connect",
        &ep,
        "--duration",
        "1",
        "--startup-timeout",
        "2",
    ]);
    let took = t0.elapsed();
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(err.contains("nothing answered at") && err.contains(&ep), "{err}");
    assert!(took < Duration::from_secs(10), "took {took:?}");
}
