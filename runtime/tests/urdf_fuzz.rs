//! The URDF reader against 330 seeded mutations of two real robots (example-robot-data's TIAGo
//! and UR5): loops, self-parents, second roots, links with two parents, huge attributes and
//! names, numbers that are not finite or not numbers, negative limits, deep nesting, missing
//! elements and attributes, unknown joint types, duplicates, cut files, DTDs, a file over the
//! size bound, one of a million nodes — and benign edits (moved, rotated, widened, reordered,
//! commented). Each case is read by a child process (this test binary, re-run on one case)
//! under a memory limit (`RLIMIT_AS`, 1 GiB) and a CPU-time limit (`RLIMIT_CPU`, 20 s), with a
//! counting allocator that measures the read's peak heap: each must end — refused in one line
//! that names the file's line or the flag at fault and quotes at most a short excerpt, or read —
//! within both bounds and with a peak heap under 32 times the file plus 16 MiB (the figures:
//! `cargo test --release -p companion-runtime --test urdf_fuzz -- --nocapture`).
//!
//! The second, independent reader is Pinocchio (urdfdom's parser, in target/py): every mutation
//! it refuses, companion refuses too, and every chain companion reads, Pinocchio reads alike —
//! the same joints, limits and speeds, and the same tip pose from the base at five seeded
//! configurations (to 1e-9 m, rad). Needs target/py with Pinocchio and example-robot-data
//! (`scripts/setup`); without it the test says so and passes, unless `COMPANION_REQUIRE_MUJOCO`
//! is set (CI sets it: the same environment as the MuJoCo plant's).
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use companion_runtime::domain::arm::urdf::{EXCERPT, MAX_BYTES, MAX_NODES};
use companion_runtime::domain::arm::{ArmDescription, HomeList, UrdfRequest};

// ----- the read's peak heap, by a counting allocator ---------------------------------------

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: delegates every call to the system allocator unchanged; only counts the bytes held.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            let now = CURRENT.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
        System.dealloc(ptr, layout);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new: usize) -> *mut u8 {
        let p = System.realloc(ptr, layout, new);
        if !p.is_null() {
            if new >= layout.size() {
                let now = CURRENT.fetch_add(new - layout.size(), Ordering::Relaxed) + new - layout.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                CURRENT.fetch_sub(layout.size() - new, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The child's address space (bytes): a read that needs more fails to allocate and the child
/// dies, which the parent reports.
const ADDRESS_SPACE: u64 = 1 << 30;
/// The child's CPU time (s): a read that loops is killed by SIGXCPU.
const CPU_SECONDS: u64 = 20;
/// A watchdog on the child's wall time (a loaded machine is slow, never this slow).
const WALL: Duration = Duration::from_secs(300);
/// The environment variable that makes this binary read one case (the child).
const CASE: &str = "COMPANION_URDF_FUZZ_CASE";
/// Cases per robot.
const PER_ROBOT: usize = 165;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn python() -> PathBuf {
    std::env::var_os("COMPANION_PYTHON")
        .map_or_else(|| workspace().join("target/py/bin/python"), PathBuf::from)
}

/// The child: reads the case named by [`CASE`] (`path\tbase\ttip\thome`) under the limits and
/// prints one line: `ok\tPEAK\tCPU_US\tNAMES` or `refused\tPEAK\tCPU_US\tMESSAGE`.
#[test]
fn child_reads_one_case() {
    let Ok(case) = std::env::var(CASE) else { return };
    let limit = |resource, value: u64| {
        let r = libc::rlimit { rlim_cur: value, rlim_max: value };
        // SAFETY: setrlimit reads the struct passed by reference; no memory is kept.
        assert_eq!(unsafe { libc::setrlimit(resource, &r) }, 0, "setrlimit");
    };
    limit(libc::RLIMIT_AS, ADDRESS_SPACE);
    limit(libc::RLIMIT_CPU, CPU_SECONDS);
    let mut f = case.split('\t');
    let (path, base, tip, home) =
        (f.next().unwrap(), f.next().unwrap(), f.next().unwrap(), f.next().unwrap());
    let request = UrdfRequest {
        path: PathBuf::from(path),
        base_link: Some(base.into()),
        tip_link: Some(tip.into()),
        home: Some(HomeList::parse(home).unwrap()),
        ..UrdfRequest::default()
    };
    let cpu = || {
        // SAFETY: getrusage writes into the struct passed; no memory is kept.
        let mut u: libc::rusage = unsafe { std::mem::zeroed() };
        unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
        let us = |t: libc::timeval| t.tv_sec * 1_000_000 + t.tv_usec;
        us(u.ru_utime) + us(u.ru_stime)
    };
    let start = cpu();
    let base_heap = CURRENT.load(Ordering::Relaxed);
    PEAK.store(base_heap, Ordering::Relaxed);
    let result = ArmDescription::from_urdf(&request);
    let peak = PEAK.load(Ordering::Relaxed) - base_heap;
    let used = cpu() - start;
    let line = match result {
        Ok(d) => format!("ok\t{peak}\t{used}\t{}", d.joint_names.join(",")),
        Err(e) => format!("refused\t{peak}\t{used}\t{}", e.to_string().replace('\n', "\\n")),
    };
    println!("\nFUZZ-RESULT\t{line}");
}

// ----- seeded mutations ---------------------------------------------------------------------

/// splitmix64: the cases are the seed's, on any machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

/// A robot's file and the chain the cases cut from it.
struct Robot {
    name: &'static str,
    text: String,
    base: &'static str,
    tip: &'static str,
    home: &'static str,
}

/// One joint of the original file: its element's byte range, its links, its chain membership.
#[derive(Clone)]
struct J {
    name: String,
    range: std::ops::Range<usize>,
    parent: String,
    child: String,
    on_chain: bool,
    moving: bool,
}

struct Parsed {
    joints: Vec<J>,
    links: Vec<(String, std::ops::Range<usize>)>,
    root: String,
    end: usize,
}

fn parse(r: &Robot) -> Parsed {
    let doc = roxmltree::Document::parse(&r.text).unwrap();
    let robot = doc.root_element();
    let links: Vec<(String, std::ops::Range<usize>)> = robot
        .children()
        .filter(|n| n.has_tag_name("link"))
        .map(|n| (n.attribute("name").unwrap().to_string(), n.range()))
        .collect();
    let mut joints: Vec<J> = robot
        .children()
        .filter(|n| n.has_tag_name("joint"))
        .map(|n| {
            let link = |t: &str| {
                n.children().find(|c| c.has_tag_name(t)).unwrap().attribute("link").unwrap().to_string()
            };
            J {
                name: n.attribute("name").unwrap().to_string(),
                range: n.range(),
                parent: link("parent"),
                child: link("child"),
                on_chain: false,
                moving: matches!(n.attribute("type"), Some("revolute" | "continuous" | "prismatic")),
            }
        })
        .collect();
    let mut link = r.tip.to_string();
    while link != r.base {
        let k = joints.iter().position(|j| j.child == link).unwrap();
        joints[k].on_chain = true;
        link = joints[k].parent.clone();
    }
    let root = links.iter().find(|(l, _)| !joints.iter().any(|j| &j.child == l)).unwrap().0.clone();
    let end = r.text.rfind("</robot>").unwrap();
    Parsed { joints, links, root, end }
}

/// The text with `edits` (byte range, replacement) applied (ranges disjoint).
fn splice(text: &str, mut edits: Vec<(std::ops::Range<usize>, String)>) -> String {
    edits.sort_by_key(|(r, _)| std::cmp::Reverse(r.start));
    let mut s = text.to_string();
    for (r, new) in edits {
        s.replace_range(r, &new);
    }
    s
}

/// The byte range of attribute `attr` of the element `tag` inside joint `j` (the joint itself
/// if `tag` is empty), as (value range), or where to insert it.
fn attr_range(text: &str, j: &J, tag: &str, attr: &str) -> Option<std::ops::Range<usize>> {
    let doc = roxmltree::Document::parse(text).ok()?;
    let node = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(&j.name))?;
    let el = if tag.is_empty() { Some(node) } else { node.children().find(|c| c.has_tag_name(tag)) }?;
    el.attributes().find(|a| a.name() == attr).map(|a| a.range_value())
}

fn element_range(text: &str, j: &J, tag: &str) -> Option<std::ops::Range<usize>> {
    let doc = roxmltree::Document::parse(text).ok()?;
    let node = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(&j.name))?;
    node.children().find(|c| c.has_tag_name(tag)).map(|c| c.range())
}

/// A joint to mutate: on the chain two times in three (its moving joints first).
fn victim<'a>(rng: &mut Rng, p: &'a Parsed, moving: bool) -> &'a J {
    let chain: Vec<&J> = p.joints.iter().filter(|j| j.on_chain && (!moving || j.moving)).collect();
    let all: Vec<&J> = p.joints.iter().filter(|j| !moving || j.moving).collect();
    let from = if rng.below(3) < 2 { chain } else { all };
    from[rng.below(from.len())]
}

const NOT_FINITE: [&str; 8] = ["nan", "NaN", "inf", "-inf", "infinity", "1e400", "-1e999", "+inf"];
const NOT_NUMBERS: [&str; 6] = ["abc", "1,5", "0x10", "", "1.2.3", "--1"];

/// The mutations' classes, by the number `mutate` draws.
const CLASSES: [&str; 30] = [
    "self-parent",
    "loop below the root",
    "loop through the root",
    "second root",
    "two parents",
    "limit not finite",
    "origin not finite",
    "negative effort/velocity",
    "huge xyz",
    "huge name",
    "deep nesting",
    "element removed",
    "limit attribute removed",
    "link removed",
    "joint type",
    "limit not a number",
    "duplicate joint",
    "duplicate link",
    "cut file",
    "zero axis",
    "mimic",
    "zero speed or limit beyond 1e3",
    "origin 1e300",
    "DTD, size, nodes",
    "moved (benign)",
    "rotated (benign)",
    "axis turned (benign)",
    "reordered (benign)",
    "speed changed (benign)",
    "comment (benign)",
];

/// One mutation of `r`: (its class, what it did, the text).
fn mutate(rng: &mut Rng, r: &Robot, p: &Parsed) -> (&'static str, String, String) {
    let t = &r.text;
    let set = |j: &J, tag: &str, attr: &str, value: &str| -> String {
        match attr_range(t, j, tag, attr) {
            Some(range) => splice(t, vec![(range, value.to_string())]),
            None => {
                // Add the attribute to the element (or the element to the joint).
                let el = if tag.is_empty() { Some(j.range.clone()) } else { element_range(t, j, tag) };
                match el {
                    Some(el) => {
                        let at = el.start + 1 + if tag.is_empty() { "joint".len() } else { tag.len() };
                        splice(t, vec![(at..at, format!(" {attr}=\"{value}\""))])
                    }
                    None => {
                        let at = j.range.end - "</joint>".len();
                        splice(t, vec![(at..at, format!("<{tag} {attr}=\"{value}\"/>"))])
                    }
                }
            }
        }
    };
    let add = |xml: &str| splice(t, vec![(p.end..p.end, xml.to_string())]);
    let kind = rng.below(CLASSES.len());
    let (detail, text) = match kind {
        0 => {
            let j = victim(rng, p, false);
            let parent = attr_range(t, j, "parent", "link").unwrap();
            (format!("self-parent {}", j.name), splice(t, vec![(parent, j.child.clone())]))
        }
        1 => {
            // A loop off the root: a joint's parent made a link below its child.
            let j = victim(rng, p, false);
            let mut under = j.child.clone();
            for _ in 0..1 + rng.below(4) {
                match p.joints.iter().find(|k| k.parent == under) {
                    Some(k) => under = k.child.clone(),
                    None => break,
                }
            }
            let parent = attr_range(t, j, "parent", "link").unwrap();
            (format!("loop below {}", j.name), splice(t, vec![(parent, under)]))
        }
        2 => {
            // A loop through the root: the root made the child of a link below it.
            let j = victim(rng, p, false);
            (
                format!("loop through the root from {}", j.child),
                add(&format!(
                    "<joint name=\"fuzz_back\" type=\"fixed\"><parent link=\"{}\"/><child link=\"{}\"/></joint>",
                    j.child, p.root
                )),
            )
        }
        3 => ("second root".into(), add("<link name=\"fuzz_orphan\"/>")),
        4 => {
            let j = victim(rng, p, false);
            let from = &rng.pick(&p.links).0;
            (
                format!("two parents of {}", j.child),
                add(&format!(
                    "<joint name=\"fuzz_second\" type=\"fixed\"><parent link=\"{from}\"/><child link=\"{}\"/></joint>",
                    j.child
                )),
            )
        }
        5 => {
            let j = victim(rng, p, true);
            let attr = *rng.pick(&["lower", "upper", "effort", "velocity"]);
            let v = *rng.pick(&NOT_FINITE);
            (format!("{} limit {attr}={v}", j.name), set(j, "limit", attr, v))
        }
        6 => {
            let j = victim(rng, p, false);
            let attr = *rng.pick(&["xyz", "rpy"]);
            let v = format!("0 {} 0", rng.pick(&NOT_FINITE));
            (format!("{} origin {attr}={v}", j.name), set(j, "origin", attr, &v))
        }
        7 => {
            let j = victim(rng, p, true);
            let attr = *rng.pick(&["effort", "velocity"]);
            (format!("{} negative {attr}", j.name), set(j, "limit", attr, "-5"))
        }
        8 => {
            let j = victim(rng, p, false);
            let n = *rng.pick(&[4usize, 100, 1_000_000, 2_500_000]);
            (format!("{} origin xyz of {n} numbers", j.name), set(j, "origin", "xyz", &"1 ".repeat(n)))
        }
        9 => {
            let j = victim(rng, p, false);
            let n = *rng.pick(&[1_000usize, 100_000, 3_000_000]);
            let name = "n".repeat(n);
            let child = attr_range(t, j, "child", "link").unwrap();
            (format!("{} child link name of {n} characters", j.name), splice(t, vec![(child, name)]))
        }
        10 => {
            let n = *rng.pick(&[400usize, 501, 600, 5_000, 200_000]);
            (
                format!("nested {n} deep"),
                add(&format!("<gazebo>{}{}</gazebo>", "<g>".repeat(n), "</g>".repeat(n))),
            )
        }
        11 => {
            let j = victim(rng, p, false);
            let tag = *rng.pick(&["parent", "child", "limit", "axis", "origin"]);
            match element_range(t, j, tag) {
                Some(range) => {
                    (format!("{} without <{tag}>", j.name), splice(t, vec![(range, String::new())]))
                }
                None => ("no edit".into(), t.clone()),
            }
        }
        12 => {
            let j = victim(rng, p, true);
            let attr = *rng.pick(&["effort", "velocity", "lower", "upper"]);
            let at = attr_range(t, j, "limit", attr);
            match at {
                // The attribute and its `="…"`.
                Some(v) => {
                    let start = t[..v.start].rfind(attr).unwrap();
                    (
                        format!("{} limit without {attr}", j.name),
                        splice(t, vec![(start..v.end + 1, String::new())]),
                    )
                }
                None => ("no edit".into(), t.clone()),
            }
        }
        13 => {
            // A link removed: its joints dangle.
            let (name, range) = rng.pick(&p.links).clone();
            (format!("link {name} removed"), splice(t, vec![(range, String::new())]))
        }
        14 => {
            let j = victim(rng, p, false);
            let v = *rng.pick(&["hinge", "", "Revolute", "floating", "planar", "ball"]);
            (format!("{} type={v}", j.name), set(j, "", "type", v))
        }
        15 => {
            let j = victim(rng, p, true);
            let attr = *rng.pick(&["lower", "upper", "velocity", "effort"]);
            let v = *rng.pick(&NOT_NUMBERS);
            (format!("{} limit {attr}={v:?}", j.name), set(j, "limit", attr, v))
        }
        16 => {
            let j = victim(rng, p, false);
            (format!("duplicate joint {}", j.name), add(&t[j.range.clone()]))
        }
        17 => {
            let (_, range) = rng.pick(&p.links).clone();
            ("duplicate link".into(), add(&t[range]))
        }
        18 => {
            let cut = p.end / 2 + rng.below(p.end / 2);
            (format!("cut at byte {cut}"), t[..cut].to_string())
        }
        19 => {
            let j = victim(rng, p, true);
            (format!("{} zero axis", j.name), set(j, "axis", "xyz", "0 0 0"))
        }
        20 => {
            let j = victim(rng, p, true);
            let at = j.range.end - "</joint>".len();
            (format!("{} a mimic", j.name), splice(t, vec![(at..at, "<mimic joint=\"x\"/>".into())]))
        }
        21 => {
            let j = victim(rng, p, true);
            let v = *rng.pick(&["0", "1e5 1e5", "5000"]);
            let attr = if v == "0" { "velocity" } else { "lower" };
            let v = if v == "1e5 1e5" { "-1e5" } else { v };
            (format!("{} {attr}={v}", j.name), set(j, "limit", attr, v))
        }
        22 => {
            let j = victim(rng, p, false);
            (format!("{} origin 1e300 away", j.name), set(j, "origin", "xyz", "1e300 0 0"))
        }
        23 => {
            let which = rng.below(3);
            match which {
                0 => ("a DTD".into(), format!("<!DOCTYPE robot [<!ENTITY a \"aaaaaaaaaa\">]>{t}")),
                1 => {
                    let n = MAX_BYTES as usize + 1024 - t.len();
                    ("over the size bound".into(), add(&format!("<!--{}-->", "x".repeat(n))))
                }
                _ => ("a million and one nodes".into(), add(&"<x/>".repeat(MAX_NODES as usize + 1))),
            }
        }
        // Benign: the file still describes a tree of the same robot, moved or rotated.
        24 => {
            let j = victim(rng, p, false);
            let v = format!("{:.6} {:.6} {:.6}", rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5);
            (format!("{} origin xyz {v}", j.name), set(j, "origin", "xyz", &v))
        }
        25 => {
            let j = victim(rng, p, false);
            let v = format!(
                "{:.6} {:.6} {:.6}",
                6.0 * rng.unit() - 3.0,
                3.0 * rng.unit() - 1.5,
                6.0 * rng.unit() - 3.0
            );
            (format!("{} origin rpy {v}", j.name), set(j, "origin", "rpy", &v))
        }
        26 => {
            let j = victim(rng, p, true);
            let v = format!("{:.6} {:.6} {:.6}", rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() + 0.1);
            (format!("{} axis {v}", j.name), set(j, "axis", "xyz", &v))
        }
        27 => {
            // A joint moved to the end of the file (the order of elements is not the tree's).
            let j = victim(rng, p, false);
            let moved = t[j.range.clone()].to_string();
            let s = splice(t, vec![(j.range.clone(), String::new()), (p.end..p.end, moved)]);
            (format!("{} moved to the end", j.name), s)
        }
        28 => {
            let j = victim(rng, p, true);
            let v = format!("{:.4}", 0.1 + 5.0 * rng.unit());
            (format!("{} velocity {v}", j.name), set(j, "limit", "velocity", &v))
        }
        _ => {
            let at = p.links[rng.below(p.links.len())].1.start;
            ("a comment".into(), splice(t, vec![(at..at, "<!-- a comment, <joint> in it -->\n".into())]))
        }
    };
    (CLASSES[kind], detail, text)
}

// ----- the cases, the parent's checks ---------------------------------------------------------

struct Outcome {
    class: &'static str,
    kind: String,
    path: PathBuf,
    bytes: usize,
    accepted: Option<Vec<String>>,
    message: String,
    peak: usize,
    cpu_us: i64,
}

/// Runs one case in a child; panics (the test fails) if the child dies or runs past the watchdog.
fn run_case(path: &Path, r: &Robot, class: &'static str, kind: &str, bytes: usize) -> Outcome {
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_reads_one_case", "--nocapture", "--test-threads", "1"])
        .env(CASE, format!("{}\t{}\t{}\t{}", path.display(), r.base, r.tip, r.home))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let end = Instant::now() + WALL;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > end {
            let _ = child.kill();
            panic!("{kind} ({}): the read ran past the {WALL:?} watchdog", path.display());
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().find_map(|l| l.strip_prefix("FUZZ-RESULT\t")).unwrap_or_else(|| {
        panic!(
            "{kind} ({}): the reader did not end within its bounds ({}; {} GiB, {CPU_SECONDS} s of CPU): {}",
            path.display(),
            out.status,
            ADDRESS_SPACE >> 30,
            String::from_utf8_lossy(&out.stderr).chars().take(2000).collect::<String>()
        )
    });
    let mut f = line.splitn(4, '\t');
    let (verdict, peak, cpu, rest) =
        (f.next().unwrap(), f.next().unwrap(), f.next().unwrap(), f.next().unwrap_or(""));
    Outcome {
        class,
        kind: kind.into(),
        path: path.into(),
        bytes,
        accepted: (verdict == "ok").then(|| rest.split(',').map(String::from).collect()),
        message: if verdict == "ok" { String::new() } else { rest.to_string() },
        peak: peak.parse().unwrap(),
        cpu_us: cpu.parse().unwrap(),
    }
}

/// What a refusal must be (module docs): one line, short, naming the file's line (or the file
/// as a whole for what has no line, or the flag), in the URDF's words.
fn check_refusal(o: &Outcome) -> Result<(), String> {
    let m = &o.message;
    let path = o.path.display().to_string();
    let lined = m.starts_with(&format!("{path}:"))
        && m[path.len() + 1..]
            .split(':')
            .next()
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
    let whole_file = [
        format!("{path} is {}", o.bytes),
        format!("{path} has more than"),
        format!("{path} has no <link>"),
        format!("{path} is not a URDF file"),
    ]
    .iter()
    .any(|p| m.starts_with(p.as_str()));
    let flag = ["--tip-link ", "--base-link ", "--home", "home of joint "].iter().any(|p| m.starts_with(p));
    if !(lined || whole_file || flag) {
        return Err("names neither a line of the file nor a flag".into());
    }
    if m.contains("\\n") {
        return Err("more than one line".into());
    }
    // The path, two quoted excerpts and two names at most, and the rule.
    if m.chars().count() > path.chars().count() + 4 * EXCERPT + 200 {
        return Err(format!("{} characters", m.chars().count()));
    }
    for internal in ["max_velocity", "joints.", "limits:", "translation", "rotation:"] {
        if m.contains(internal) {
            return Err(format!("an internal name ({internal})"));
        }
    }
    Ok(())
}

/// The robots' files (example-robot-data in target/py), or why there are none.
fn robots() -> Result<[Robot; 2], String> {
    let out = Command::new(python())
        .args(["-c", "import sysconfig, pinocchio; print(sysconfig.get_paths()['purelib'])"])
        .output()
        .map_err(|e| format!("{}: {e}", python().display()))?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
    }
    let dir = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim())
        .join("cmeel.prefix/share/example-robot-data/robots");
    let read = |rel: &str| std::fs::read_to_string(dir.join(rel)).map_err(|e| format!("{rel}: {e}"));
    Ok([
        Robot {
            name: "tiago",
            text: read("tiago_description/robots/tiago_no_hand.urdf")?,
            base: "base_footprint",
            tip: "arm_tool_link",
            home: "0.2,1.0,-0.5,-1.0,1.2,0.0,0.5,0.0",
        },
        Robot {
            name: "ur5",
            text: read("ur_description/urdf/ur5_robot.urdf")?,
            base: "base_link",
            tip: "tool0",
            home: "0.3,-1.0,1.2,-1.4,-1.5,0.2",
        },
    ])
}

/// Pinocchio's reading of every case, one JSON object a line
/// (`runtime/tests/urdf_fuzz/pinocchio_reads.py`), restarted after a case it cannot survive
/// (noted as refused by it).
fn pinocchio(cases: &[serde_json::Value]) -> BTreeMap<usize, serde_json::Value> {
    let mut got = BTreeMap::new();
    let mut from = 0;
    while from < cases.len() {
        let input = serde_json::to_string(&cases[from..]).unwrap();
        let mut p = Command::new(python())
            .arg(workspace().join("runtime/tests/urdf_fuzz/pinocchio_reads.py"))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        p.stdin.take().unwrap().write_all(input.as_bytes()).unwrap();
        let reader = std::io::BufReader::new(p.stdout.take().unwrap());
        for line in reader.lines().map_while(Result::ok) {
            let v: serde_json::Value = serde_json::from_str(&line).unwrap();
            got.insert(v["id"].as_u64().unwrap() as usize, v);
        }
        let _ = p.wait();
        let next =
            cases[from..].iter().position(|c| !got.contains_key(&(c["id"].as_u64().unwrap() as usize)));
        match next {
            None => break,
            Some(k) => {
                let id = cases[from + k]["id"].as_u64().unwrap() as usize;
                got.insert(
                    id,
                    serde_json::json!({"id": id, "ok": false, "error": "Pinocchio's process died on it"}),
                );
                from += k + 1;
            }
        }
    }
    got
}

#[test]
fn mutated_urdfs_are_refused_in_bounded_time_and_memory_or_read_as_pinocchio_reads_them() {
    if std::env::var_os(CASE).is_some() {
        return;
    }
    let robots = match robots() {
        Ok(r) => r,
        Err(why) => {
            assert!(
                std::env::var_os("COMPANION_REQUIRE_MUJOCO").is_none(),
                "COMPANION_REQUIRE_MUJOCO is set but target/py lacks Pinocchio or example-robot-data: {why}"
            );
            eprintln!("SKIPPED: the URDF fuzz needs target/py with Pinocchio and example-robot-data (scripts/setup): {why}");
            return;
        }
    };
    let started = Instant::now();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("urdf-fuzz-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = Rng(0x5EED_0045);
    let mut outcomes = Vec::new();
    let mut failures = Vec::new();
    for r in &robots {
        let p = parse(r);
        for k in 0..PER_ROBOT {
            let (class, kind, text) = mutate(&mut rng, r, &p);
            let path = dir.join(format!("{}-{k:03}.urdf", r.name));
            std::fs::write(&path, &text).unwrap();
            let o = run_case(&path, r, class, &kind, text.len());
            // A case's file can be large: only the accepted ones are kept for Pinocchio.
            if let Err(why) = o.accepted.as_ref().map_or_else(|| check_refusal(&o), |_| Ok(())) {
                failures.push(format!("{} {kind}: {why}: {}", path.display(), o.message));
            }
            // The read's peak heap: the text, the parsed tree (about 70 bytes a node, a node for
            // every 2 to 7 bytes of a file of tiny elements) and the chain.
            let bound = 32 * o.bytes + (16 << 20);
            if o.peak > bound {
                failures.push(format!("{} {kind}: peak heap {} bytes over {bound}", path.display(), o.peak));
            }
            outcomes.push((r, o));
        }
    }
    // Pinocchio on every case whose file is small enough to hand it (all but the size and
    // node-count cases), with the configurations at which the accepted chains are compared.
    let mut cases = Vec::new();
    for (id, (r, o)) in outcomes.iter().enumerate() {
        if o.bytes > 8 << 20 {
            continue;
        }
        let mut qs = Vec::new();
        if let Some(names) = &o.accepted {
            let d = ArmDescription::from_urdf(&UrdfRequest {
                path: o.path.clone(),
                base_link: Some(r.base.into()),
                tip_link: Some(r.tip.into()),
                home: Some(HomeList::parse(r.home).unwrap()),
                ..UrdfRequest::default()
            })
            .unwrap();
            let mut q_rng = Rng(id as u64);
            for _ in 0..5 {
                let q: Vec<f64> = d
                    .joints
                    .iter()
                    .map(|j| {
                        let [lo, hi] = j.limits;
                        let (lo, hi) = (lo.max(-3.0), hi.min(3.0));
                        lo + (hi - lo) * q_rng.unit()
                    })
                    .collect();
                let pose = end_effector(&d, &q);
                qs.push(serde_json::json!({"q": q, "pose": pose}));
            }
            let limits: Vec<[f64; 2]> = d.joints.iter().map(|j| j.limits).collect();
            let speed: Vec<f64> = d.joints.iter().map(|j| j.max_velocity).collect();
            cases.push(serde_json::json!({
                "id": id, "path": o.path, "base": r.base, "tip": r.tip, "joints": names, "qs": qs,
                "limits": limits.iter().map(|l| [json_num(l[0]), json_num(l[1])]).collect::<Vec<_>>(),
                "velocity": speed.iter().map(|v| json_num(*v)).collect::<Vec<_>>(),
            }));
        } else {
            cases.push(serde_json::json!({"id": id, "path": o.path, "base": r.base, "tip": r.tip}));
        }
    }
    let pin = pinocchio(&cases);
    let (mut both_refuse, mut only_companion, mut both_read) = (0, 0, 0);
    // Per class: (companion and Pinocchio refuse, companion alone refuses, both read alike,
    // not handed to Pinocchio).
    let mut by_class: BTreeMap<&str, [usize; 4]> = BTreeMap::new();
    for (id, (_, o)) in outcomes.iter().enumerate() {
        if !cases.iter().any(|c| c["id"].as_u64() == Some(id as u64)) {
            by_class.entry(o.class).or_default()[3] += 1;
        }
    }
    for c in &cases {
        let id = c["id"].as_u64().unwrap() as usize;
        let (_, o) = &outcomes[id];
        let p = &pin[&id];
        let pin_ok = p["ok"].as_bool().unwrap_or(false);
        match (&o.accepted, pin_ok) {
            (None, false) => {
                both_refuse += 1;
                by_class.entry(o.class).or_default()[0] += 1;
            }
            (None, true) => {
                only_companion += 1;
                by_class.entry(o.class).or_default()[1] += 1;
            }
            (Some(_), false) => failures.push(format!(
                "{} {}: companion reads it, Pinocchio (urdfdom) refuses it: {}",
                o.path.display(),
                o.kind,
                p["error"]
            )),
            (Some(_), true) => {
                both_read += 1;
                by_class.entry(o.class).or_default()[2] += 1;
                if let Some(e) = p["mismatch"].as_str() {
                    failures.push(format!(
                        "{} {}: Pinocchio reads it otherwise: {e}",
                        o.path.display(),
                        o.kind
                    ));
                }
            }
        }
    }
    let refused = outcomes.iter().filter(|(_, o)| o.accepted.is_none()).count();
    let peak = outcomes.iter().map(|(_, o)| o.peak).max().unwrap_or(0);
    let (worst_ratio, worst) = outcomes
        .iter()
        .map(|(_, o)| (o.peak as f64 / o.bytes as f64, o))
        .fold((0.0, None), |(m, w), (x, o)| if x > m { (x, Some(o)) } else { (m, w) });
    let cpu = outcomes.iter().map(|(_, o)| o.cpu_us).max().unwrap_or(0);
    let slowest =
        outcomes.iter().max_by_key(|(_, o)| o.cpu_us).map(|(_, o)| o.kind.clone()).unwrap_or_default();
    println!(
        "{} cases ({} per robot): {refused} refused, {} read; largest peak heap {:.1} MB, largest peak/file {worst_ratio:.1} ({}), \
         largest CPU time {:.3} s ({slowest}); Pinocchio on {}: both refuse {both_refuse}, only companion refuses \
         {only_companion}, both read alike {both_read}; {:.1} s in all",
        outcomes.len(),
        PER_ROBOT,
        outcomes.len() - refused,
        peak as f64 / 1e6,
        worst.map_or(String::new(), |o| o.kind.clone()),
        cpu as f64 / 1e6,
        cases.len(),
        started.elapsed().as_secs_f64()
    );
    println!("  class: both refuse / companion alone refuses / both read alike / too large for Pinocchio");
    for (class, [a, b, c, d]) in &by_class {
        println!("  {class}: {a} / {b} / {c} / {d}");
    }
    for (_, o) in outcomes.iter().filter(|(_, o)| o.accepted.is_none()).step_by(23) {
        println!("  e.g. {}: {}", o.kind.chars().take(60).collect::<String>(), o.message);
    }
    assert!(failures.is_empty(), "{} of {} cases:\n{}", failures.len(), outcomes.len(), failures.join("\n"));
    assert!(outcomes.len() >= 300 && both_read >= 30 && refused >= 150, "too few of a kind to mean much");
    let _ = std::fs::remove_dir_all(&dir);
}

fn json_num(x: f64) -> serde_json::Value {
    if x.is_finite() {
        serde_json::json!(x)
    } else {
        serde_json::Value::Null
    }
}

/// The tip's pose from the base at `q` (companion's chain): the rotation row by row, then the
/// position.
fn end_effector(d: &ArmDescription, q: &[f64]) -> Vec<f64> {
    use companion_core::nalgebra::SVector;
    fn at<const N: usize>(d: &ArmDescription, q: &[f64]) -> Vec<f64> {
        let c = d.chain::<f64, N>().unwrap();
        let e = c.end_effector(&SVector::<f64, N>::from_fn(|i, _| q[i]));
        let r = e.rotation;
        (0..3).flat_map(|i| (0..3).map(move |j| r[(i, j)])).chain(e.translation.iter().copied()).collect()
    }
    match q.len() {
        6 => at::<6>(d, q),
        7 => at::<7>(d, q),
        _ => at::<8>(d, q),
    }
}
