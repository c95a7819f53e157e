//! Mutual TLS over Zenoh (the default across machines): a run between the right peers, and
//! every wrong peer refused — no certificate, another CA's, an expired one, the right CA's with
//! the wrong name, a plaintext peer, a rogue that comes first — with 0 commands applied and the
//! plant's exit code and message saying why; frames of the wrong size for 10 s and a flood of
//! connection attempts while a real controller runs. Loopback only.

use std::sync::OnceLock;
use std::time::SystemTime;

use companion_runtime::transport::certs::{write_pair, Deployment, Host, Validity};

use super::*;

/// The TLS material of the tests: deployment A (its CA; `plant` valid for 127.0.0.1; `ctrl`;
/// `rogue`, same CA, another name; `expired`, named `ctrl` but no longer valid), deployment B
/// (another CA; its own `ctrl`), and C made by `companion certs` itself.
struct Pki {
    a: PathBuf,
    b: PathBuf,
    c: PathBuf,
}

fn pki() -> &'static Pki {
    static PKI: OnceLock<Pki> = OnceLock::new();
    PKI.get_or_init(|| {
        let root = dir("tls-pki");
        let (a, b) = (root.join("a"), root.join("b"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        let ok = Validity::days(2);
        let day = Duration::from_secs(86_400);
        let past = Validity { start: SystemTime::now() - 10 * day, end: SystemTime::now() - day };
        let ca = Deployment::new(ok).unwrap();
        write_pair(&a, "ca", &ca.ca()).unwrap();
        let host = |s: &str| Host::parse(s).unwrap();
        for (file, h, v) in [
            ("plant", "plant=127.0.0.1", ok),
            ("ctrl", "ctrl", ok),
            ("rogue", "rogue", ok),
            ("expired", "ctrl", past),
        ] {
            write_pair(&a, file, &ca.host(&host(h), v).unwrap()).unwrap();
        }
        let other = Deployment::new(ok).unwrap();
        write_pair(&b, "ca", &other.ca()).unwrap();
        write_pair(&b, "ctrl", &other.host(&host("ctrl"), ok).unwrap()).unwrap();
        let c = root.join("c");
        let (st, out, err) =
            run(&["certs", "--out", c.to_str().unwrap(), "--hosts", "plant=127.0.0.1,ctrl", "--days", "2"]);
        assert!(st.success(), "{out}\n{err}");
        assert!(out.contains("--tls-peer ctrl") && out.contains("--tls-peer plant"), "{out}");
        Pki { a, b, c }
    })
}

/// `quic/127.0.0.1:PORT` (the secure default: QUIC under mutual TLS) on a UDP port that was
/// free a moment ago.
fn free_tls_endpoint() -> String {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    format!("quic/127.0.0.1:{}", s.local_addr().unwrap().port())
}

/// The TLS flags of a side: CA of `ca_dir`, the pair `dir/NAME.{pem,key}`, the peer's name.
fn tls_flags(ca_dir: &Path, dir: &Path, file: &str, peer: &str) -> Vec<String> {
    let p = |f: &str| dir.join(f).display().to_string();
    vec![
        "--tls-ca".into(),
        ca_dir.join("ca.pem").display().to_string(),
        "--tls-cert".into(),
        p(&format!("{file}.pem")),
        "--tls-key".into(),
        p(&format!("{file}.key")),
        "--tls-peer".into(),
        peer.into(),
    ]
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The plant of deployment A listening on `ep` for `ctrl` (lockstep unless `rt` flags are
/// given), writing into `out`.
fn plant_a(ep: &str, n: &str, out: &Path, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> =
        ["plant", "--transport", "zenoh", "--listen", ep, "--no-plots", "--quiet", "--name", n]
            .map(String::from)
            .to_vec();
    v.extend(["--out".into(), out.display().to_string()]);
    v.extend(tls_flags(&pki().a, &pki().a, "plant", "ctrl"));
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

/// A controller connecting to `ep` for demo `n` with `flags` (its security).
fn control_with(ep: &str, n: &str, flags: &[String], extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = ["control", "--transport", "zenoh", "--connect", ep, "--quiet", "--name", n]
        .map(String::from)
        .to_vec();
    v.extend(flags.iter().cloned());
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

/// Nothing of the run was written: the plant never served a command.
fn nothing_applied(out: &Path) {
    for f in ["timeseries.csv", "summary.json", "latency.json"] {
        assert!(!out.join(f).exists(), "{} exists: the plant ran", out.join(f).display());
    }
}

#[test]
fn a_tls_run_between_the_right_peers_succeeds_and_summary_records_the_link() {
    let _g = serial();
    let c = &pki().c;
    let (n, d) = (name("tlsok"), dir("tls-ok"));
    let ep = free_tls_endpoint();
    let lock = ["--lockstep", "--duration", "1"];
    let mut plant: Vec<String> =
        ["--transport", "zenoh", "--listen", &ep, "--no-plots", "--name", &n, "--out", d.to_str().unwrap()]
            .map(String::from)
            .to_vec();
    plant.extend(tls_flags(c, c, "plant", "ctrl"));
    plant.extend(lock.map(String::from));
    let control = control_with(&ep, &n, &tls_flags(c, c, "ctrl", "plant"), &lock);
    let ((pst, perr), (cst, cerr)) = two_roles(&strs(&plant), &strs(&control[1..]));
    assert!(pst.success(), "plant: {perr}");
    assert!(cst.success(), "controller: {cerr}");
    let link = &json(&d.join("summary.json"))["link"];
    assert_eq!(link["insecure"], false, "{link}");
    let t = link["transport"].as_str().unwrap();
    assert!(t.contains(&ep) && t.contains("mutual TLS") && t.contains("ctrl"), "{t}");
    assert!(!perr.contains("--insecure"), "{perr}");
    // The lock files are gone after a clean end.
    for role in ["plant", "control"] {
        let lock = Path::new(companion_runtime::sys::lock::LOCK_DIR).join(format!("{n}.{role}.lock"));
        assert!(!lock.exists(), "{} left behind", lock.display());
    }
}

#[test]
fn plain_tcp_is_refused_without_insecure_and_recorded_with_it() {
    let _g = serial();
    let ep = free_endpoint();
    for role in [["plant", "--listen"], ["control", "--connect"]] {
        let (st, _, err) = run(&[role[0], "--transport", "zenoh", role[1], &ep, "--duration", "1"]);
        assert_eq!(st.code(), Some(2), "{err}");
        assert!(
            err.contains("is plain TCP") && err.contains("--insecure") && err.contains("companion certs"),
            "{err}"
        );
    }
    // TLS without its files: which flag is missing.
    let tls = free_tls_endpoint();
    let (st, _, err) = run(&["plant", "--transport", "zenoh", "--listen", &tls, "--duration", "1"]);
    assert_eq!(st.code(), Some(2), "{err}");
    assert!(err.contains("--tls-ca"), "{err}");
    // --insecure: warned at start, recorded in summary.json.
    let (n, d) = (name("tlsinsecure"), dir("tls-insecure"));
    let common =
        ["--transport", "zenoh", "--insecure", "--lockstep", "--duration", "1", "--no-plots", "--name", &n];
    let ((pst, perr), (cst, cerr)) = two_roles(
        &[&["--listen", &ep, "--out", d.to_str().unwrap()], &common[..]].concat(),
        &[&["--connect", &ep], &common[..]].concat(),
    );
    assert!(pst.success() && cst.success(), "{perr}\n{cerr}");
    for err in [&perr, &cerr] {
        assert!(err.contains("warning: --insecure") && err.contains("anyone"), "{err}");
    }
    let link = &json(&d.join("summary.json"))["link"];
    assert_eq!(link["insecure"], true, "{link}");
}

/// A plant of deployment A, and a peer that must be refused (`peer`: starts it, returns
/// what to drop after the plant ended): the plant exits 2 naming `why`, having written
/// nothing.
fn refused_by_the_plant(tag: &str, why: &[&str], peer: impl FnOnce(&str, &str) -> Box<dyn FnOnce()>) {
    let _g = serial();
    let (n, d) = (name(tag), dir(tag));
    let ep = free_tls_endpoint();
    let out = d.join("out");
    let mut plant = Demo::start(&strs(&plant_a(
        &ep,
        &n,
        &out,
        &["--lockstep", "--duration", "1", "--startup-timeout", "8"],
    )));
    plant.wait_line("waiting for its controller", HANG);
    let done = peer(&ep, &n);
    let (pst, pseen) = plant.wait(HANG);
    done();
    assert_eq!(pst.code(), Some(2), "{pseen:#?}");
    let all = pseen.join("\n");
    assert!(all.contains("no control joined"), "{all}");
    for w in why {
        assert!(all.contains(w), "{w:?} not in {all}");
    }
    nothing_applied(&out);
}

/// A `companion control` started in the background (its end awaited when dropped).
fn control_in_background(args: Vec<String>) -> Box<dyn FnOnce()> {
    let c = Demo::start(&strs(&args));
    Box::new(move || {
        let (st, seen) = c.wait(HANG);
        assert_eq!(st.code(), Some(2), "the refused controller: {seen:#?}");
    })
}

/// A controller with `file`'s certificate from `cert_ca`'s folder, trusting deployment A's CA,
/// refused by deployment A's plant with every one of `why` in the plant's message.
fn refused_controller(tag: &str, why: &[&str], cert_ca: &Path, file: &str) {
    refused_by_the_plant(tag, why, |ep, n| {
        control_in_background(control_with(
            ep,
            n,
            &tls_flags(&pki().a, cert_ca, file, "plant"),
            &["--startup-timeout", "4"],
        ))
    });
}

#[test]
fn a_controller_of_another_ca_is_refused() {
    // It trusts A's CA (so it would accept the plant), but its own certificate is B's.
    refused_controller("tls-other-ca", &["refused a TLS handshake", "UnknownIssuer"], &pki().b, "ctrl");
}

#[test]
fn an_expired_controller_certificate_is_refused() {
    refused_controller("tls-expired", &["refused a TLS handshake", "xpired"], &pki().a, "expired");
}

#[test]
fn a_controller_with_the_right_ca_and_the_wrong_name_is_refused_and_named() {
    refused_controller(
        "tls-wrong-name",
        &["refused the peer at", "\"rogue\", not \"ctrl\""],
        &pki().a,
        "rogue",
    );
}

#[test]
fn a_plaintext_controller_against_a_tls_plant_is_refused() {
    // Over QUIC (UDP) a plain TCP peer never reaches the listener: the kernel resets its
    // connection; the plant names nobody, serves nobody, and the controller exits 2.
    refused_by_the_plant("tls-plaintext", &[], |ep, n| {
        let tcp = ep.replacen("quic/", "tcp/", 1);
        control_in_background(control_with(&tcp, n, &["--insecure".to_string()], &["--startup-timeout", "4"]))
    });
}

#[test]
fn a_controller_without_a_certificate_is_refused() {
    refused_by_the_plant("tls-no-cert", &["refused a TLS handshake", "no certificate"], |ep, _| {
        // A TLS client that checks the plant against A's CA but presents no certificate
        // (the companion command line cannot be told to: it always presents one).
        let ca = json_path(pki().a.join("ca.pem"));
        let tls = [
            ("transport/link/tls/root_ca_certificate", ca),
            ("transport/link/tls/enable_mtls", "false".into()),
        ];
        let s = raw_session(ep, &tls);
        Box::new(move || drop(s))
    });
}

/// A path as a JSON string (for zenoh's configuration).
fn json_path(p: PathBuf) -> String {
    serde_json::Value::String(p.display().to_string()).to_string()
}

/// A raw Zenoh peer session connecting to `ep` (retrying in the background), with the TLS
/// settings `tls` (key, JSON5 value).
fn raw_session(ep: &str, tls: &[(&str, String)]) -> zenoh::Session {
    use zenoh::Wait;
    let mut c = zenoh::Config::default();
    let common = [
        ("mode", "\"peer\"".to_string()),
        ("scouting/multicast/enabled", "false".into()),
        ("listen/endpoints", "[]".into()),
        ("connect/endpoints", format!("[\"{ep}\"]")),
        ("connect/timeout_ms", "-1".into()),
        ("connect/exit_on_failure", "false".into()),
    ];
    for (k, v) in common.iter().chain(tls) {
        c.insert_json5(k, v).unwrap();
    }
    zenoh::open(c).wait().unwrap()
}

/// A raw Zenoh session of deployment A connecting to `ep` with the pair `file`.
fn session_of_a(ep: &str, file: &str) -> zenoh::Session {
    let a = &pki().a;
    let tls = [
        ("transport/link/tls/root_ca_certificate", json_path(a.join("ca.pem"))),
        ("transport/link/tls/connect_certificate", json_path(a.join(format!("{file}.pem")))),
        ("transport/link/tls/connect_private_key", json_path(a.join(format!("{file}.key")))),
        ("transport/link/tls/enable_mtls", "true".into()),
    ];
    raw_session(ep, &tls)
}

#[test]
fn a_rogue_that_connects_first_is_refused_named_and_the_real_controller_served() {
    use zenoh::Wait;
    let _g = serial();
    let a = &pki().a;
    let (n, d) = (name("tlsrogue"), dir("tls-rogue"));
    let ep = free_tls_endpoint();
    let rt = relaxed(&["--duration", "3"]);
    let mut plant = Demo::start(&strs(&plant_a(&ep, &n, &d, &rt)));
    plant.wait_line("waiting for its controller", HANG);
    // The rogue: the deployment's CA, another name, and everything a controller of this demo
    // does — a liveliness token of the controller's role, commands on the commands' key —
    // from another machine (a raw session: a second `companion control` here would only meet
    // this machine's lock of the demo's name).
    let rogue = session_of_a(&ep, "rogue");
    let v = companion_runtime::transport::wire::PROTOCOL_VERSION;
    let _token =
        rogue.liveliness().declare_token(format!("companion/{n}/v{v}/alive/control/4242")).wait().unwrap();
    let publisher = rogue.declare_publisher(format!("companion/{n}/v{v}/command")).wait().unwrap();
    let size = std::mem::size_of::<companion_runtime::transport::wire::CommandMsg>();
    // Refused and named before the real controller starts.
    let (_, line) = plant.wait_line("refused the peer at", HANG);
    assert!(line.contains("\"rogue\", not \"ctrl\""), "{line}");
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sent = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let mut sent = 0u64;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                publisher.put(vec![0xFFu8; size]).wait().unwrap();
                publisher.put(vec![0u8; 7]).wait().unwrap();
                sent += 2;
                std::thread::sleep(Duration::from_millis(2));
            }
            sent
        })
    };
    let (cst, _, cerr) = run(&strs(&control_with(&ep, &n, &tls_flags(a, a, "ctrl", "plant"), &rt)));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let sent = sent.join().unwrap();
    assert!(cst.success(), "{cerr}");
    let (pst, pseen) = plant.wait(HANG);
    drop(rogue);
    assert!(pst.success(), "{pseen:#?}");
    assert!(sent > 100, "the rogue sent {sent} frames");
    // Nothing of the rogue reached the plant: no invalid command, no frame of the wrong size.
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["cycles"], 3001, "{lat:#}");
    assert_eq!(lat["invalid_total"], 0, "{lat:#}");
    assert!(!pseen.iter().any(|l| l.contains("wrong size")), "{pseen:#?}");
}

/// The plant's resident memory (kB), from /proc.
fn rss_kb(pid: u32) -> u64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = s.lines().find(|l| l.starts_with("VmRSS:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// A real-time run of deployment A's plant and controller (`seconds` long, not about real
/// time), the plant's pid and the output folder, once the plant's loop has written rows.
fn served_run(tag: &str, seconds: &str, log_every: &str) -> (Demo, Demo, String, String, PathBuf) {
    let a = &pki().a;
    let (n, d) = (name(tag), dir(tag));
    let ep = free_tls_endpoint();
    let rt = relaxed(&["--duration", seconds, "--log-every", log_every]);
    let plant = Demo::start(&strs(&plant_a(&ep, &n, &d, &rt)));
    let control = Demo::start(&strs(&control_with(&ep, &n, &tls_flags(a, a, "ctrl", "plant"), &rt)));
    wait_rows(&d.join("timeseries.csv"), 1);
    (plant, control, ep, n, d)
}

#[test]
fn frames_of_the_wrong_size_or_content_for_10_s_are_counted_dropped_never_applied() {
    use zenoh::Wait;
    let _g = serial();
    let (plant, control, ep, n, d) = served_run("tls-garbage", "16", "10");
    let pid = plant.child.id();
    // A peer of the deployment (its certificate is right) that sends garbage on the commands'
    // key: truncated, oversized, empty, and of the right size but not a command.
    let s = session_of_a(&ep, "ctrl");
    let publisher = s
        .declare_publisher(format!(
            "companion/{n}/v{}/command",
            companion_runtime::transport::wire::PROTOCOL_VERSION
        ))
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .wait()
        .unwrap();
    let end = Instant::now() + HANG;
    while !publisher.matching_status().wait().unwrap().matching() {
        assert!(Instant::now() < end, "the plant's subscriber never matched");
        std::thread::sleep(Duration::from_millis(10));
    }
    let size = std::mem::size_of::<companion_runtime::transport::wire::CommandMsg>();
    let sizes = [0, 1, size - 1, size + 1, 4096, 65_536];
    let (mut wrong, mut garbage) = (0u64, 0u64);
    let (start, mut rss0) = (Instant::now(), 0);
    // 10 s of frames, 200 a second (the count is what is checked, not the time).
    while start.elapsed() < Duration::from_secs(10) {
        for &n in &sizes {
            publisher.put(vec![0xA5u8; n]).wait().unwrap();
            wrong += 1;
        }
        publisher.put(vec![0xFFu8; size]).wait().unwrap();
        garbage += 1;
        if garbage == 100 {
            rss0 = rss_kb(pid);
        }
        std::thread::sleep(Duration::from_millis(35));
    }
    let rss1 = rss_kb(pid);
    let (pst, pseen) = plant.wait(HANG);
    let (cst, cseen) = control.wait(HANG);
    drop(s);
    assert!(pst.success(), "plant: {pseen:#?}");
    assert!(cst.success(), "controller: {cseen:#?}");
    let said = format!("plant: {wrong} messages of the wrong size dropped by the transport");
    assert!(pseen.iter().any(|l| l.contains(&said)), "{said:?} not in {pseen:#?}");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["invalid_total"], garbage, "{lat:#}");
    // Memory: bounded (zenoh's buffers are reused), whatever the frames.
    assert!(rss1 < rss0 + 64 * 1024, "the plant grew from {rss0} kB to {rss1} kB");
    println!("garbage over TLS: {wrong} frames of the wrong size, {garbage} of the right size; plant RSS {rss0} → {rss1} kB");
}

#[test]
fn a_flood_of_connection_attempts_leaves_the_served_run_intact() {
    let _g = serial();
    let (plant, control, ep, _, d) = served_run("tls-flood", "16", "1");
    let addr = ep.strip_prefix("quic/").unwrap().to_string();
    // 1 000 attempts from this process, paced over 10 s, loopback only: each a fresh UDP
    // socket sending what is not a QUIC handshake (a line of HTTP, then a datagram shaped like
    // a QUIC long-header Initial with garbage after it), which the listener must drop.
    let csv = d.join("timeseries.csv");
    let rows =
        || std::fs::read(&csv).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count().saturating_sub(1));
    let flood_from = rows();
    let mut made = 0;
    for i in 0..1000u32 {
        if let Ok(s) = std::net::UdpSocket::bind("127.0.0.1:0") {
            let mut initial = vec![0xc3, 0, 0, 0, 1, 8];
            initial.extend((0..1200u32).map(|k| (k.wrapping_mul(2_654_435_761).wrapping_add(i) >> 7) as u8));
            if s.send_to(b"GET / HTTP/1.0\r\n\r\n", &addr).is_ok() && s.send_to(&initial, &addr).is_ok() {
                made += 1;
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let flood_to = rows();
    let (pst, pseen) = plant.wait(HANG);
    let (cst, cseen) = control.wait(HANG);
    assert!(pst.success(), "plant: {pseen:#?}\ncontroller: {cseen:#?}");
    assert!(cst.success(), "controller: {cseen:#?}");
    assert!(made > 900, "{made} connections of 1000");
    let lat = json(&d.join("latency.json"));
    assert_eq!(lat["cycles"], 16_001, "{lat:#}");
    assert_eq!(lat["invalid_total"], 0, "{lat:#}");
    // The misses (periods whose command came late: held) during the flood and apart from it;
    // figures only (a loaded test machine misses for its own reasons; the run's verdict is
    // the check).
    let statuses = csv_statuses(&csv);
    let held = |r: std::ops::Range<usize>| statuses[r].iter().filter(|s| *s == "held").count();
    let (from, to) = (flood_from.min(statuses.len()), flood_to.min(statuses.len()));
    let (during, apart) = (held(from..to), held(0..from) + held(to..statuses.len()));
    println!(
        "flood over QUIC: {made} bogus handshakes dropped; misses during the flood {during} of {} periods, \
         apart from it {apart} of {} (the run's total {})",
        to - from,
        statuses.len() - (to - from),
        lat["deadline_misses"]
    );
}
