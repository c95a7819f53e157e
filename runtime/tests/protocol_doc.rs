//! `docs/book/src/bridge.md` against the code it describes.
//!
//! - Its exit-code table (§6, marked `<!-- exit-codes: control -->`) and its sentence on
//!   `companion plant`'s codes (`<!-- exit-codes: plant -->`) against the CLI's one list,
//!   [`exit::EXIT_CODES`] (`runtime/src/cli/exit.rs`, included here by path), which `--help`
//!   prints: the same codes, each row naming what the code means; every "exit N" of the
//!   document is one of them; `--help` prints the list.
//! - The HIL chapter's table of every command's exit codes (`docs/book/src/hil.md`, marked
//!   `<!-- exit-codes: all -->`) against the same list.
//! - The warning `companion control` gives for the plant's flags it ignores, as §4 quotes it.
//! - Its Python snippets marked `<!-- doc-test: python -->` (§2: node and prefix, the two
//!   messages, services and ports; §4: waiting for the peer's ports and the scan for other
//!   protocol versions; liveness: the `Node.list` unwrapping), run as written, in order, as one
//!   program with `python3` against the pinned binding (iceoryx2 0.10.0) and a live
//!   `companion control`. One line is changed: `NAME = "demo"` becomes a name of this test's
//!   own, so that a demo running on the machine is not touched. The test's own Python (marked
//!   as such in the program it writes) runs before them — it waits until the controller has
//!   created its services, so that the two do not race to create them — and after them: it
//!   calls the snippets' functions, checks the scan finds no other version, sends a handshake
//!   measurement built from the snippet's `Measurement` and receives the controller's answer
//!   with the snippet's `receive`, then SIGKILLs the controller and watches the snippet's
//!   `peer_state` go from "alive" to "dead" (cleaning its resources) to "absent". The Rust
//!   snippet and the `text` blocks are not run.
//!
//! The Python test needs `python3` with `iceoryx2==0.10.0` (`scripts/setup` installs it);
//! without them it says so and passes — unless `COMPANION_REQUIRE_BRIDGE` is set (CI sets
//! it), when their absence fails.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

#[allow(dead_code)]
#[path = "../src/cli/exit.rs"]
mod exit;

use exit::{ExitCodeDoc, EXIT_CODES};

const BIN: &str = env!("CARGO_BIN_EXE_companion");

fn doc() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/book/src/bridge.md");
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Whether `command` exits with `e`'s code.
fn applies_to(e: &ExitCodeDoc, command: &str) -> bool {
    e.commands.is_empty() || e.commands.contains(&command)
}

fn codes_of(command: &str) -> Vec<u8> {
    EXIT_CODES.iter().filter(|e| applies_to(e, command)).map(|e| e.code).collect()
}

/// The lines after the (only) line `marker`.
fn after_marker<'a>(doc: &'a str, marker: &str) -> Vec<&'a str> {
    let lines: Vec<&str> = doc.lines().collect();
    let at: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].trim() == marker).collect();
    assert_eq!(at.len(), 1, "the document must have exactly one line {marker:?}");
    lines[at[0] + 1..].to_vec()
}

/// The rows of the table right after `marker`: `(code, the whole row)`.
fn table_rows<'a>(doc: &'a str, marker: &str) -> Vec<(u8, &'a str)> {
    let lines = after_marker(doc, marker);
    let table: Vec<&str> = lines.iter().copied().take_while(|l| l.starts_with('|')).collect();
    assert!(table.len() > 2, "no table after {marker:?}");
    table[2..]
        .iter()
        .map(|row| {
            let cell = row.trim_start_matches('|').split('|').next().unwrap_or("").trim();
            let code = cell.parse().unwrap_or_else(|e| panic!("{marker}: row {row:?}: code {cell:?}: {e}"));
            (code, *row)
        })
        .collect()
}

/// The numbers of a list like "0, 2, 3 and 130".
fn numbers(text: &str) -> Vec<u8> {
    text.split(|c: char| !c.is_ascii_digit()).filter(|w| !w.is_empty()).map(|w| w.parse().unwrap()).collect()
}

#[test]
fn the_exit_code_list_is_ordered_and_has_every_exit_constant() {
    let codes: Vec<u8> = EXIT_CODES.iter().map(|e| e.code).collect();
    let mut sorted = codes.clone();
    sorted.sort_unstable();
    sorted.dedup();
    assert_eq!(codes, sorted, "EXIT_CODES: one entry per code, in increasing order");
    for c in [
        exit::EXIT_ERROR,
        exit::EXIT_PEER_LOST,
        exit::EXIT_PEER_HUNG,
        exit::EXIT_NAME_IN_USE,
        exit::EXIT_REJECTED,
        exit::EXIT_DEADLINES,
        exit::EXIT_CHAOS_MISMATCH,
        exit::EXIT_PANIC,
        exit::EXIT_INTERRUPTED,
    ] {
        assert!(codes.contains(&c), "exit code {c} is not in EXIT_CODES");
    }
    for e in EXIT_CODES {
        assert!(e.meaning.contains(e.key), "exit code {}: its key {:?} is not in its meaning", e.code, e.key);
    }
}

/// `--help` of every command that lists exit codes prints the list.
#[test]
fn help_prints_the_exit_code_list() {
    let table = exit::help();
    for e in EXIT_CODES {
        assert!(
            table.contains(&format!("\n{:>5}    ", e.code)),
            "exit code {} not in the table:\n{table}",
            e.code
        );
    }
    for command in [None, Some("sim"), Some("hil"), Some("plant"), Some("control"), Some("latency")] {
        let mut c = Command::new(BIN);
        c.args(command).arg("--help");
        let out = c.output().unwrap();
        assert!(out.status.success(), "{command:?} --help");
        let help = String::from_utf8_lossy(&out.stdout);
        assert!(help.contains(&table), "{command:?} --help does not print EXIT_CODES:\n{help}");
    }
}

/// The table of every command's exit codes in the HIL chapter (`docs/book/src/hil.md`, marked
/// `<!-- exit-codes: all -->`) against the same list: every code, in order, each row saying
/// what the code means (its key phrase, the row's backticks aside).
#[test]
fn the_hil_chapters_exit_codes_are_the_clis() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/book/src/hil.md");
    let doc = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let rows = table_rows(&doc, "<!-- exit-codes: all -->");
    let documented: Vec<u8> = rows.iter().map(|(c, _)| *c).collect();
    let all: Vec<u8> = EXIT_CODES.iter().map(|e| e.code).collect();
    assert_eq!(
        documented, all,
        "hil.md: the exit codes (left) differ from runtime/src/cli/exit.rs's (right)"
    );
    for (code, row) in &rows {
        let e = EXIT_CODES.iter().find(|e| e.code == *code).unwrap();
        assert!(
            row.replace('`', "").contains(e.key),
            "hil.md: the row of exit code {code} does not say {:?} (EXIT_CODES: {:?}):\n{row}",
            e.key,
            e.meaning
        );
    }
}

#[test]
fn the_documents_exit_codes_are_the_clis() {
    let doc = doc();
    let rows = table_rows(&doc, "<!-- exit-codes: control -->");
    let documented: Vec<u8> = rows.iter().map(|(c, _)| *c).collect();
    assert_eq!(
        documented,
        codes_of("control"),
        "bridge.md §6: the codes of `companion control` (left) differ from runtime/src/cli/exit.rs's \
         EXIT_CODES (right)"
    );
    for (code, row) in &rows {
        let e = EXIT_CODES.iter().find(|e| e.code == *code).unwrap();
        assert!(
            row.contains(e.key),
            "bridge.md §6: the row of exit code {code} does not say {:?} (EXIT_CODES: {:?}):\n{row}",
            e.key,
            e.meaning
        );
    }

    // "`companion plant` uses 0, 2, … and 130 the same way".
    let text = after_marker(&doc, "<!-- exit-codes: plant -->").join(" ");
    let list = text
        .split_once("uses")
        .and_then(|(_, rest)| rest.split_once("the same way"))
        .map(|(list, _)| list)
        .unwrap_or_else(|| {
            panic!("no \"`companion plant` uses … the same way\" after the marker: {text:.200}")
        });
    assert_eq!(numbers(list), codes_of("plant"), "bridge.md §6: the codes of `companion plant`");

    // Every "exit N", "exit code N", "exits N" anywhere in the document is a code of the list.
    let known: BTreeSet<u8> = EXIT_CODES.iter().map(|e| e.code).collect();
    for pattern in ["exit ", "exit code ", "exits ", "exits with "] {
        for (at, _) in doc.match_indices(pattern) {
            let rest = &doc[at + pattern.len()..];
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            if let Ok(code) = digits.parse::<u8>() {
                assert!(
                    known.contains(&code),
                    "the bridge chapter mentions {pattern}{code}, not an exit code"
                );
            }
        }
    }
}

// ----- the Python snippets ------------------------------------------------------------------

/// Whether `python3` with iceoryx2 0.10.0 is here; says why not.
fn python_available() -> bool {
    let probe = Command::new("python3")
        .args(["-c", "import iceoryx2, importlib.metadata as m; print(m.version('iceoryx2'))"])
        .output();
    let why = match probe {
        Err(e) => format!("python3 not found ({e})"),
        Ok(o) if !o.status.success() => {
            format!("python3 has no iceoryx2 module ({})", String::from_utf8_lossy(&o.stderr).trim())
        }
        Ok(o) if String::from_utf8_lossy(&o.stdout).trim() != "0.10.0" => {
            format!("python3 has iceoryx2 {}, not 0.10.0", String::from_utf8_lossy(&o.stdout).trim())
        }
        Ok(_) => return true,
    };
    assert!(
        std::env::var_os("COMPANION_REQUIRE_BRIDGE").is_none(),
        "COMPANION_REQUIRE_BRIDGE is set but the doc's Python snippets cannot run: {why}"
    );
    eprintln!("SKIPPED: the doc's Python snippets need python3 with iceoryx2==0.10.0 (scripts/setup): {why}");
    false
}

/// The blocks of `doc` marked `<!-- doc-test: python -->`, in order, each dedented.
fn python_snippets(doc: &str) -> Vec<String> {
    let lines: Vec<&str> = doc.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if lines[i].trim() != "<!-- doc-test: python -->" {
            i += 1;
            continue;
        }
        let fence = lines.get(i + 1).copied().unwrap_or("");
        assert_eq!(fence.trim(), "```python", "a doc-test marker must be followed by a ```python block");
        let indent = fence.len() - fence.trim_start().len();
        let mut block = String::new();
        i += 2;
        while i < lines.len() && lines[i].trim() != "```" {
            block.push_str(lines[i].get(indent..).unwrap_or(lines[i].trim_start()));
            block.push('\n');
            i += 1;
        }
        assert!(i < lines.len(), "a doc-test block is not closed");
        out.push(block);
        i += 1;
    }
    out
}

/// Waits for `c` at most `limit` (killed after it: a hang fails the test); status, stdout,
/// stderr.
fn finish(mut c: Child, limit: Duration, what: &str) -> (ExitStatus, String, String) {
    let end = Instant::now() + limit;
    while c.try_wait().unwrap().is_none() {
        if Instant::now() > end {
            let _ = c.kill();
            let out = c.wait_with_output().unwrap();
            panic!(
                "{what} still running after {limit:?}; it wrote:\n{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let o = c.wait_with_output().unwrap();
    (
        o.status,
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The test's own Python before the snippets: wait until the controller's services exist.
const PRELUDE: &str = r#"# ----- test harness (runtime/tests/protocol_doc.rs), not from the document -----
import iceoryx2 as _iox, time as _time
_cfg = _iox.config.default()
_cfg.global_cfg.prefix = _iox.FileName.new("companion_")
_end = _time.monotonic() + 30
while not all(
    _iox.Service.does_exist(_iox.ServiceName.new(f"companion/{_NAME}/v4/{_s}"), _cfg,
                            _iox.MessagingPattern.PublishSubscribe, _iox.ServiceType.Ipc)
    for _s in ("measurement", "command")
):
    assert _time.monotonic() < _end, "companion control created no services within 30 s"
    _time.sleep(0.01)
"#;

/// The test's own Python after the snippets: use what they define against the controller.
const EPILOGUE: &str = r#"
# ----- test harness (runtime/tests/protocol_doc.rs), not from the document -----
import math, os, signal, sys
assert other_versions() == [], other_versions()
ids = peer_ids()
assert len(ids) == 1, f"the command service's other nodes: {ids}"
print("peer", peer_state(ids), flush=True)
# The handshake: measurement 0 of a lockstep unicycle with the paper's arm at the start of
# trajectory 1 (no scenario or arm check).
m = Measurement(version=4, flags=2, seq=0, session=0x1234_5678_9ABC_DEF1, plant_time_ns=time.monotonic_ns(),
                dt=0.001, platform=1, hold_periods=20, joint_count=3, space=1)
m.joints[0:3] = (0.0, 0.35, 0.0)
m.target_position[:] = (2.6, 1.0, 0.0)
m.target_rotation[:] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
m.target_twist[:] = (0.0, -math.pi / 20, 0.0, 0.0, 0.0, 0.0)
publish(m)
end = time.monotonic() + 20
while (got := receive()) is None:
    assert time.monotonic() < end, "no answer to the handshake within 20 s"
    time.sleep(0.001)
command, sender = got
assert (command.version, command.seq, command.session) == (4, 0, m.session), (command.version, command.seq)
assert (command.status, command.joint_count, command.platform, command.space) == (0, 3, 1, 1), command.status
assert math.isfinite(command.v) and math.isfinite(command.ep_norm) and command.joint_scale >= 1.0
assert peer_ids(sender) == [sender] and sender in ids
print("answer", command.status, flush=True)
os.kill(int(os.environ["COMPANION_DOC_PEER_PID"]), signal.SIGKILL)
end = time.monotonic() + 20
while (state := peer_state([sender])) == "alive":
    assert time.monotonic() < end, "the killed controller still alive after 20 s"
    time.sleep(0.005)
# "dead" (and cleaned), or "absent" when another process cleaned it first: creating an
# iceoryx2 node under the prefix cleans dead nodes.
print("peer", state, flush=True)
# Cleaning can find nothing to clean right after the death (the process still exiting): the
# next look retries.
looks = 1
while (state := peer_state([sender])) == "dead":
    assert time.monotonic() < end, "the killed controller's node not cleaned within 20 s"
    looks += 1
    time.sleep(0.005)
print("peer", state, flush=True)
print("looks until cleaned:", looks, file=sys.stderr)
"#;

fn scratch(tag: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("protocol-doc-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_documents_python_snippets_run_against_the_pinned_binding_and_a_live_controller() {
    let snippets = python_snippets(&doc());
    assert!(snippets.len() >= 4, "expected the doc-test snippets of §2 and §4, found {}", snippets.len());
    if !python_available() {
        return;
    }
    let name = format!("pd{}", std::process::id());
    let program = snippets.concat();
    let line = "NAME = \"demo\"  # the demo's name (companion control --name NAME)";
    assert_eq!(program.matches(line).count(), 1, "the snippets must set NAME once, as {line:?}");
    let program = program.replace(line, &format!("NAME = {name:?}"));
    let script = scratch("snippets").join("snippets.py");
    std::fs::write(&script, format!("_NAME = {name:?}\n{PRELUDE}\n{program}{EPILOGUE}")).unwrap();

    let control = Command::new(BIN)
        .args(["control", "--name", &name, "--startup-timeout", "60", "--peer-timeout", "60", "--quiet"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = control.id();
    // Reaped as soon as it ends: a killed process that stays a zombie is reported dead by
    // iceoryx2, but its resources are not cleaned.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(control.wait_with_output());
    });
    let python = Command::new("python3")
        .arg(&script)
        .env("COMPANION_DOC_PEER_PID", pid.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (status, out, err) = finish(python, Duration::from_secs(120), "the doc's Python snippets");
    if !status.success() {
        // The snippets failed before they killed it: end it.
        let _ = companion_runtime::sys::process::send_signal(
            i32::try_from(pid).unwrap(),
            companion_runtime::sys::process::Signal::Terminate,
        );
    }
    let controller =
        rx.recv_timeout(Duration::from_secs(30)).expect("companion control still running").unwrap();
    let ct = String::from_utf8_lossy(&controller.stderr);
    // The name lock of a killed controller (a file it could not remove).
    let _ = std::fs::remove_file(
        Path::new(companion_runtime::sys::lock::LOCK_DIR).join(format!("{name}.control.lock")),
    );
    assert!(
        status.success(),
        "the doc's Python snippets failed ({status}) ({}):\n{out}\n{err}\ncontroller:\n{ct}",
        script.display()
    );
    assert!(
        !controller.status.success(),
        "the controller was killed, yet exited with {}:\n{ct}",
        controller.status
    );
    let seen: Vec<&str> = out.lines().collect();
    let gone = seen.get(2).copied().unwrap_or("");
    assert!(
        seen.len() == 4
            && seen[..2] == ["peer alive", "answer 0"]
            && ["peer dead", "peer absent"].contains(&gone)
            && seen[3] == "peer absent",
        "the snippets' output, expected peer alive, answer 0, peer dead (or absent), peer absent ({}):\n{out}\n{err}",
        script.display()
    );
    eprintln!("the killed controller was found {gone:?} first");
}

/// `companion control` warns about the plant's flags it ignores, in the words the document
/// quotes, and says nothing of them when they are not given.
#[test]
fn control_warns_about_the_plant_flags_it_ignores_as_the_document_says() {
    let quoted = "warning: companion control ignores --duration, --lockstep: the plant decides them";
    let doc = doc().split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(doc.contains(&format!("*\"{quoted} …\"*")), "bridge.md §4 no longer quotes {quoted:?}");
    let name = format!("pdw{}", std::process::id());
    let run = |extra: &[&str]| {
        let c = Command::new(BIN)
            .args(["control", "--name", &name, "--startup-timeout", "0"])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (status, _, err) = finish(c, Duration::from_secs(60), "companion control");
        assert_eq!(
            status.code(),
            Some(i32::from(exit::EXIT_ERROR)),
            "no plant within --startup-timeout 0:\n{err}"
        );
        err
    };
    let err = run(&["--duration", "5", "--lockstep"]);
    assert!(err.contains(quoted), "companion control --duration 5 --lockstep:\n{err}");
    let err = run(&["--out", "elsewhere", "--delay", "0.001", "--lockstep"]);
    assert!(err.contains("ignores --lockstep, --delay, --out: the plant decides them"), "{err}");
    let err = run(&[]);
    let _ = std::fs::remove_file(
        Path::new(companion_runtime::sys::lock::LOCK_DIR).join(format!("{name}.control.lock")),
    );
    assert!(!err.contains("ignores"), "companion control without the plant's flags:\n{err}");
}
