//! The HIL demo over Zenoh (cargo feature `zenoh`): lockstep determinism, a peer killed, a
//! partition, and bad endpoints — the same exit codes and reports as over iceoryx2. Faults
//! across a network are injected by a forwarding proxy on loopback ([`proxy`]); the tests
//! start and stop everything they use. `companion hil` and the namespace tests run over TLS
//! (the default); the tests of the link's faults between `plant` and `control` over plain TCP
//! (`--insecure`), whose failures are the same; [`tls`] tests who is refused.

#[path = "over_zenoh/netns.rs"]
mod netns;
#[path = "over_zenoh/proxy.rs"]
mod proxy;
#[path = "over_zenoh/tls.rs"]
mod tls;

use std::net::TcpListener;
use std::sync::Arc;

use self::netns::NetnsPair;
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
        let mut common = vec![
            "--transport",
            "zenoh",
            "--insecure",
            "--lockstep",
            "--duration",
            "3",
            "--no-plots",
            "--name",
            &n,
        ];
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
    // Every injected command is counted by the plant, or the link's loss is: zenoh drops a
    // publication on congestion without an error at the sender (its queue of two batches
    // full for 1 ms), which shows only as the controller's sent count above the plant's
    // received one (link.json).
    let link = json(&d.join("link.json"));
    let (sent, got) =
        (link["controller"]["published"].as_u64().unwrap(), link["plant"]["received"].as_u64().unwrap());
    let lost = link["commands_not_received"].as_u64().unwrap();
    assert_eq!(lost, sent.saturating_sub(got), "{link:#}");
    assert_eq!(lat["link_counts"], link["plant"], "latency.json has the plant's counts");
    assert_eq!(link["plant"]["malformed"], 0);
    let invalid = lat["invalid_total"].as_u64().unwrap();
    assert!(invalid <= 4 && invalid + lost >= 4, "{invalid} counted invalid, {lost} lost: {lat:#}\n{link:#}");
    if lost == 0 {
        assert_eq!(invalid, 4, "nothing lost, so every injected command was counted: {lat:#}");
    }
    assert!(sent > 4, "{link:#}");
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
    wait_rows(&d.join("timeseries.csv"), 500);
    signal(pid, "KILL");
    let killed = Instant::now();
    let (noticed, line) = demo.wait_line("died", Duration::from_secs(10));
    println!("controller noticed the killed plant after {:?}: {line}", noticed.duration_since(killed));
    let (st, seen) = demo.wait(Duration::from_secs(20));
    assert_eq!(st.code(), Some(3), "{seen:#?}");
    assert!(seen.iter().any(|l| l.contains("killed by signal 9")), "{seen:#?}");
    let statuses = csv_statuses(&d.join("timeseries.csv"));
    // At least the 500 rows seen before the kill (a starved plant may have written none since).
    assert!(statuses.len() >= 500, "{} rows", statuses.len());
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
    wait_rows(&d.join("timeseries.csv"), 500);
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
    let mut common =
        vec!["--transport", "zenoh", "--insecure", "--no-plots", "--quiet", "--log-every", "1", "--name", &n];
    common.extend(extra);
    let plant = spawn(&[&["plant", "--listen", &ep, "--out", out], &common[..]].concat());
    let control = spawn(&[&["control", "--connect", &pe], &common[..]].concat());
    (proxy, plant, control, d)
}

#[test]
fn a_cut_network_is_a_dead_peer_hold_stop_report_clean_exit_codes() {
    let _g = serial();
    // The network cut (connections closed): both sides find the peer gone at once.
    let (proxy, plant, control, d) =
        through_proxy("zenoh-cut", Duration::ZERO, &["--duration", "20", "--hold-periods", "5"]);
    wait_rows(&d.join("timeseries.csv"), 500);
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
}

#[test]
fn a_silent_network_is_a_hung_peer_hold_stop_report_clean_exit_codes() {
    let _g = serial();
    // A silent network (connections kept, nothing forwarded): the peer is alive but silent,
    // hung after --peer-timeout.
    let (proxy, plant, control, d) = through_proxy(
        "zenoh-stall",
        Duration::ZERO,
        &["--duration", "20", "--hold-periods", "5", "--peer-timeout", "1"],
    );
    wait_rows(&d.join("timeseries.csv"), 500);
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
    // Names of their own: on the default name `demo` these runs would meet (and be refused by)
    // any other demo or test run on this machine (seen: a second test run's controller).
    let n = name("zbad");
    let (st, _, err) = run(&[
        "plant",
        "--transport",
        "zenoh",
        "--insecure",
        "--name",
        &n,
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
    // (That it gives up rather than hangs is the harness's watchdog; how soon is not asserted.)
    let ep = free_endpoint();
    let (st, _, err) = run(&[
        "control",
        "--transport",
        "zenoh",
        "--insecure",
        "--name",
        &n,
        "--connect",
        &ep,
        "--startup-timeout",
        "2",
    ]);
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(err.contains("nothing answered at") && err.contains(&ep), "{err}");
}

#[test]
fn a_plant_of_another_scenario_over_zenoh_is_refused_and_both_sides_say_why() {
    let _g = serial();
    let d = dir("zenoh-refused");
    let n = name("zrefused");
    let ep = free_endpoint();
    let out = d.to_str().unwrap();
    let plant = [
        "--transport",
        "zenoh",
        "--insecure",
        "--listen",
        &ep,
        "--lockstep",
        "--choice",
        "b",
        "--duration",
        "1",
    ];
    let (plant, control) = two_roles(
        &[&plant[..], &["--no-plots", "--name", &n, "--out", out]].concat(),
        &["--transport", "zenoh", "--insecure", "--connect", &ep, "--name", &n, "--choice", "a"],
    );
    scenario_refused(&d, plant, control);
}

/// The protocol version of the fake peer: the next one after this program's.
const OTHER_VERSION: u32 = companion_runtime::transport::wire::PROTOCOL_VERSION + 1;

/// A Zenoh peer of protocol version [`OTHER_VERSION`] on demo `n`, listening on `ep`: its
/// token, as a later version following this one's convention would declare it. Returns the
/// session and the token keys it saw.
fn other_version_peer(
    ep: &str,
    n: &str,
) -> (zenoh::Session, zenoh::liveliness::LivelinessToken, Arc<Mutex<Vec<String>>>) {
    use zenoh::Wait;
    let mut c = zenoh::Config::default();
    for (k, v) in [
        ("mode", "\"peer\"".to_string()),
        ("scouting/multicast/enabled", "false".into()),
        ("listen/endpoints", format!("[\"{ep}\"]")),
    ] {
        c.insert_json5(k, &v).unwrap();
    }
    let s = zenoh::open(c).wait().unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&seen);
    s.liveliness()
        .declare_subscriber(format!("companion/{n}/**"))
        .callback(move |sample: zenoh::sample::Sample| {
            sink.lock().unwrap().push(sample.key_expr().as_str().to_string());
        })
        .background()
        .wait()
        .unwrap();
    let token = s
        .liveliness()
        .declare_token(format!("companion/{n}/v{OTHER_VERSION}/alive/plant/4242"))
        .wait()
        .unwrap();
    (s, token, seen)
}

#[test]
fn a_peer_of_another_protocol_version_over_zenoh_is_named() {
    let _g = serial();
    let n = name("zversion");
    let ep = free_endpoint();
    let (_session, _token, seen) = other_version_peer(&ep, &n);
    // Named at once, not at the start-up timeout: with a timeout of an hour, a controller that
    // only gave up at it would be caught by the harness's watchdog — no clock is read here.
    let (st, _, err) = run(&[
        "control",
        "--transport",
        "zenoh",
        "--insecure",
        "--connect",
        &ep,
        "--name",
        &n,
        "--startup-timeout",
        "3600",
    ]);
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(
        err.contains("protocol version mismatch")
            && err.contains(&format!("with protocol version {OTHER_VERSION}"))
            && err.contains("process 4242")
            && err.contains(&format!("this program speaks version {}", OTHER_VERSION - 1)),
        "{err}"
    );
    // The other side saw our version's token: a peer that checks as we do names us too.
    let seen = seen.lock().unwrap();
    assert!(
        seen.iter().any(|k| k.starts_with(&format!("companion/{n}/v{}/alive/control/", OTHER_VERSION - 1))),
        "{seen:?}"
    );
}

#[test]
fn a_second_controller_over_zenoh_is_refused_and_the_run_goes_on() {
    let _g = serial();
    let d = dir("zenoh-second");
    let n = name("zsecond");
    let ep = free_endpoint();
    let out = d.to_str().unwrap();
    let common = ["--transport", "zenoh", "--insecure", "--no-plots", "--quiet", "--name", &n];
    let rt = ["--hold-periods", LOADED_HOLD, "--max-miss-fraction", "1"];
    let plant =
        spawn(&[&["plant", "--listen", &ep, "--duration", "4", "--out", out], &rt[..], &common[..]].concat());
    let first = spawn(&[&["control", "--connect", &ep], &common[..]].concat());
    // The first controller is served: the plant's loop has written rows.
    wait_rows(&d.join("timeseries.csv"), 1);
    let (st, _, err) = run(&[&["control", "--connect", &ep, "--startup-timeout", "5"], &common[..]].concat());
    assert_eq!(st.code(), Some(5), "{err}");
    assert!(err.contains("is already running"), "{err}");
    let (fst, fseen) = first.wait(Duration::from_secs(20));
    let (pst, pseen) = plant.wait(Duration::from_secs(20));
    assert!(fst.success(), "first controller: {fseen:#?}\nplant: {pseen:#?}");
    assert!(pst.success(), "plant: {pseen:#?}");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["invalid_total"], 0, "no command of the second controller reached the plant: {lat:#}");
}

/// The summary's `max_ep_norm_after_20s` (the floor), or the final ‖e_p‖ of a shorter run.
fn floor_of(d: &Path, seconds: f64) -> f64 {
    let s = json(&d.join("summary.json"));
    let key = if seconds >= 25.0 { "max_ep_norm_after_20s" } else { "final_ep_norm" };
    s[key].as_f64().unwrap_or_else(|| panic!("{key} in {s:#}"))
}

/// Real time at 1 kHz over Zenoh, the plant applying answers up to 8 periods old: without
/// delay, with 2 ms each way through the delaying proxy and the delay compensation, and the
/// same without it. `COMPANION_ZENOH_DELAY_S` sets the duration: by default 6 s (CI: the
/// mechanism — older answers applied, the delay measured and announced, no stop); 30 s gives
/// the floors after 20 s that docs/book/src/two-machines.md quotes, and then the aims are
/// asserted (compensated ≤ 2× the undelayed floor, uncompensated ≥ 10× the compensated).
#[test]
fn two_ms_each_way_is_compensated_in_real_time() {
    let _g = serial();
    let seconds: f64 =
        std::env::var("COMPANION_ZENOH_DELAY_S").ok().and_then(|s| s.parse().ok()).unwrap_or(6.0);
    let dur = seconds.to_string();
    let rt = [
        "--duration",
        &dur,
        "--max-command-age",
        "8",
        // Not the load-proof 100 000: the joint guard is κ = 1/(hold + 2), and 1/100 002
        // would freeze the arm (every floor ~0.7 m).
        "--hold-periods",
        "50",
        "--max-miss-fraction",
        "1",
    ];
    let mut floors = Vec::new();
    for (tag, delay, comp) in [
        ("zdelay-none", Duration::ZERO, true),
        ("zdelay-comp", Duration::from_millis(2), true),
        ("zdelay-raw", Duration::from_millis(2), false),
    ] {
        let extra: &[&str] = if comp { &[] } else { &["--no-delay-compensation"] };
        let (proxy, plant, control, d) = through_proxy(tag, delay, &[&rt[..], extra].concat());
        let (cst, cseen) = control.wait(Duration::from_secs(60 + 2 * seconds as u64));
        let (pst, pseen) = plant.wait(Duration::from_secs(30));
        drop(proxy);
        assert!(cst.success(), "{tag} controller: {cseen:#?}");
        assert!(pst.success(), "{tag} plant: {pseen:#?}");
        let lat = json(&d.join("latency.json"));
        let (fresh, aged, misses) = (
            lat["fresh_commands"].as_u64().unwrap(),
            lat["aged_commands"].as_u64().unwrap(),
            lat["deadline_misses"].as_u64().unwrap(),
        );
        let cycles = lat["cycles"].as_u64().unwrap();
        let rt50 = lat["round_trip_ns"]["p50"].as_u64().unwrap_or(0);
        let floor = floor_of(&d, seconds);
        println!(
            "{tag}: floor {floor:.3e}; {cycles} cycles, {fresh} fresh of which {aged} older answers, {misses} \
             misses; plant's round trip p50 {rt50} ns; controller: {}",
            cseen.iter().find(|l| l.contains("delay predicted over")).map_or("", String::as_str)
        );
        // The subject is what the delay does to the answers that came, counted among them: a
        // loaded machine (CPU-pressure back-offs) misses more deadlines, which is not this
        // test's business (it once required 90 % of the periods fresh and failed at 89 %
        // with four builds beside it); the loop must have run in real time at all.
        assert!(fresh * 2 >= cycles, "{tag}: {fresh} fresh of {cycles}");
        if delay.is_zero() {
            // Without delay most answers come in their own period; a late controller on a
            // loaded machine makes some older (10.5 % in one CI run beside builds), never the
            // ≥ 90 % that 2 ms each way gives.
            assert!(aged * 2 < fresh, "{tag}: {aged} older answers of {fresh} without delay");
        } else {
            // Every answer comes ~4 periods late, and the plant's clock says so.
            assert!(aged * 10 >= fresh * 9, "{tag}: {aged} older answers of {fresh}");
            assert!(rt50 > 4_000_000 && rt50 < 6_000_000, "{tag}: round trip p50 {rt50} ns");
        }
        floors.push(floor);
    }
    let [none, comp, raw] = floors[..] else { unreachable!() };
    println!(
        "T1 (a) at 1 kHz over Zenoh, {seconds} s: without delay {none:.3e}, 2 ms each way compensated {comp:.3e} \
         ({:.2}×), uncompensated {raw:.3e} ({:.0}×)",
        comp / none,
        raw / none
    );
    // The floors exist only after the approach (T1 (a) converges within ~20 s).
    if seconds >= 25.0 {
        assert!(comp <= 2.0 * none, "compensated {comp:e} vs undelayed {none:e}");
        assert!(raw >= 10.0 * comp, "compensation helps: {comp:e} vs {raw:e}");
    }
}

/// Two network namespaces joined by a veth pair, or `None` with the reason printed (the test
/// then skips: namespaces need root).
fn namespaces(tag: u8) -> Option<NetnsPair> {
    match NetnsPair::create(tag) {
        Ok(p) => Some(p),
        Err(e) => {
            // CI runs as root and sets this: there the tests must run, not skip.
            assert!(
                std::env::var_os("COMPANION_REQUIRE_NETNS").is_none(),
                "COMPANION_REQUIRE_NETNS is set but network namespaces cannot be made: {e}"
            );
            eprintln!(
                "SKIPPED: network namespaces are not available here ({e}); run as root to test across them"
            );
            None
        }
    }
}

/// `companion ARGS` in network namespace `ns`.
fn in_namespace(ns: &str, args: &[&str]) -> Demo {
    let mut c = Command::new("ip");
    c.args(["netns", "exec", ns, BIN]).args(args);
    Demo::spawn(c)
}

/// The plant in one namespace listening on its veth address, the controller in the other
/// connecting to it over mutual TLS: the two-machine setup of docs/book/src/two-machines.md on
/// one machine, its certificates made by `companion certs` as the chapter says.
fn across_namespaces(pair: &NetnsPair, tag: &str, extra: &[&str]) -> (Demo, Demo, PathBuf) {
    let d = dir(tag);
    let n = name(tag);
    let certs = d.join("certs");
    let hosts = format!("plant.local={},ctrl.local", pair.addr_a);
    let (st, out, err) = run(&["certs", "--out", certs.to_str().unwrap(), "--hosts", &hosts]);
    assert!(st.success(), "{out}\n{err}");
    let f = |x: &str| certs.join(x).display().to_string();
    let (ca, pc, pk, cc, ck) =
        (f("ca.pem"), f("plant.local.pem"), f("plant.local.key"), f("ctrl.local.pem"), f("ctrl.local.key"));
    let ep = format!("quic/{}:7447", pair.addr_a);
    let mut common = vec!["--transport", "zenoh", "--no-plots", "--quiet", "--log-every", "1", "--name", &n];
    common.extend(extra);
    let plant_tls = ["--tls-ca", &ca, "--tls-cert", &pc, "--tls-key", &pk, "--tls-peer", "ctrl.local"];
    let control_tls = ["--tls-ca", &ca, "--tls-cert", &cc, "--tls-key", &ck, "--tls-peer", "plant.local"];
    let out = d.join("out");
    let plant = in_namespace(
        &pair.a,
        &[
            &["plant", "--listen", "quic/0.0.0.0:7447", "--out", out.to_str().unwrap()],
            &plant_tls[..],
            &common[..],
        ]
        .concat(),
    );
    let control =
        in_namespace(&pair.b, &[&["control", "--connect", &ep], &control_tls[..], &common[..]].concat());
    (plant, control, out)
}

#[test]
fn plant_and_controller_in_two_network_namespaces() {
    let _g = serial();
    let Some(pair) = namespaces(1) else { return };
    let rt = ["--duration", "3", "--hold-periods", LOADED_HOLD, "--max-miss-fraction", "1"];
    let (plant, control, d) = across_namespaces(&pair, "znetns", &rt);
    let (cst, cseen) = control.wait(Duration::from_secs(60));
    let (pst, pseen) = plant.wait(Duration::from_secs(30));
    assert!(cst.success(), "controller: {cseen:#?}");
    assert!(pst.success(), "plant: {pseen:#?}");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["cycles"], 3001, "{lat:#}");
    println!(
        "across namespaces {} → {}: plant's round trip p50 {} ns, {} fresh commands of 3001",
        pair.b, pair.a, lat["round_trip_ns"]["p50"], lat["fresh_commands"]
    );
    drop(pair);
}

/// Over QUIC (the default) a link taken down ends each side's session when the peer's lease
/// (half its `--peer-timeout`) runs out with nothing heard: found dead or unreachable (exit
/// 3), before the loops would call it hung (exit 4, after `--peer-timeout`).
#[test]
fn a_link_down_between_namespaces_is_an_unreachable_peer_hold_stop_report() {
    let _g = serial();
    let Some(pair) = namespaces(2) else { return };
    let (plant, control, d) = across_namespaces(
        &pair,
        "znetns-down",
        &["--duration", "20", "--hold-periods", "5", "--peer-timeout", "1"],
    );
    wait_rows(&d.join("timeseries.csv"), 500);
    pair.link_down().unwrap();
    let (cst, cseen) = control.wait(Duration::from_secs(20));
    let (pst, pseen) = plant.wait(Duration::from_secs(20));
    assert_eq!(cst.code(), Some(3), "controller: {cseen:#?}");
    assert_eq!(pst.code(), Some(3), "plant: {pseen:#?}");
    assert!(cseen.iter().any(|l| l.contains("died or is unreachable")), "{cseen:#?}");
    let reason = json(&d.join("latency.json"))["end"].as_str().unwrap().to_string();
    assert!(reason.contains("died or is unreachable") && reason.contains("robot stopped"), "{reason}");
    held_then_stopped(&csv_statuses(&d.join("timeseries.csv")), 5);
    drop(pair);
}
