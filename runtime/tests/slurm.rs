//! `companion explore`'s Slurm job array (`docs/book/src/explore-tune.md`, "On a Slurm cluster") on a
//! real single-node Slurm: munge, slurmctld and slurmd from Debian's packages (Slurm 22.05),
//! configured in a temporary folder on free ports, started by this test and stopped by it
//! (also when it fails).
//!
//! The doc's three blocks (`<!-- slurm: script -->`, `submit`, `rerun`) run as written, the
//! script scaled down to 4 shards of a small sweep (its array range, `N`, cores and sample
//! count replaced; nothing else). Task 2 is suspended mid-shard (a journal line written, no
//! results): a second process on its folder must be refused (exit 9) and merge must call it
//! still running; then it is cancelled, the `afterok` merge must be cancelled by Slurm
//! (`DependencyNeverSatisfied`), merge must call the shard unfinished and not running, and
//! the doc's rerun block must resume it from its journal and merge. Every file the merge
//! writes must equal the unsharded run's, byte for byte.
//!
//! Waits are for counted states (job states from `scontrol`, files), never for a time; one
//! generous watchdog bounds the whole test.
//!
//! Skipped, with the reason printed, where the Slurm and munge programs are missing or the
//! test is not root (slurmd runs jobs as their user); with `COMPANION_REQUIRE_SLURM` set (CI
//! sets it; its `scripts/setup` installs them) that is a failure instead.

use std::collections::BTreeMap;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_companion");

/// The whole test's bound (s): far above the ~30 s it takes on an idle 2-core machine.
const WATCHDOG_S: u64 = 900;

/// The programs the test needs.
const PROGRAMS: [&str; 8] =
    ["munged", "slurmctld", "slurmd", "sbatch", "squeue", "scontrol", "scancel", "sinfo"];

/// The sweep: 4 shards of 96 samples (car, realistic limits, run 1c, 40 s each: about 2 s of
/// work per shard).
const SHARDS: u64 = 4;
const SAMPLES: u64 = 96;

fn find(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/sbin", "/usr/bin"].map(PathBuf::from))
        .map(|d| d.join(program))
        .find(|p| p.is_file())
}

/// Why the test cannot run here, if it cannot.
fn unavailable() -> Option<String> {
    let missing: Vec<&str> = PROGRAMS.iter().copied().filter(|p| find(p).is_none()).collect();
    if !missing.is_empty() {
        return Some(format!(
            "not installed: {} (Debian: apt-get install slurm-wlm munge; scripts/setup does)",
            missing.join(", ")
        ));
    }
    let uid = Command::new("id")
        .arg("-u")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    if uid.as_deref() != Some("0") {
        return Some("not root: slurmd must run jobs as their user".into());
    }
    None
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map(|a| a.port()).expect("a free port")
}

/// The single-node cluster: its folder and daemons. Dropping it cancels every job, stops the
/// daemons (SIGTERM to the ones it started, by pid), and removes the folder unless the test
/// failed (then it is kept and named, with the daemons' logs).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    node: String,
    daemons: Vec<(&'static str, Child)>,
    deadline: Instant,
}

impl Cluster {
    fn start(deadline: Instant) -> Self {
        let dir = std::env::temp_dir().join(format!("companion-slurm-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for d in ["state", "spool", "log", "work"] {
            std::fs::create_dir_all(dir.join(d)).unwrap();
        }
        let mut cluster = Cluster {
            conf: dir.join("slurm.conf"),
            dir,
            node: "companion1".into(),
            daemons: Vec::new(),
            deadline,
        };
        let d = cluster.dir.clone();
        // munge: a key of its own, its own socket.
        let key = d.join("munge.key");
        let mut bytes = vec![0u8; 1024];
        {
            use std::io::Read as _;
            std::fs::File::open("/dev/urandom").unwrap().read_exact(&mut bytes).unwrap();
        }
        std::fs::write(&key, &bytes).unwrap();
        set_mode(&key, 0o400);
        let socket = d.join("munge.sock");
        let munged = Command::new(find("munged").unwrap())
            .arg("--foreground")
            .arg("--force")
            .arg(format!("--socket={}", socket.display()))
            .arg(format!("--key-file={}", key.display()))
            .arg(format!("--pid-file={}", d.join("munged.pid").display()))
            .arg(format!("--log-file={}", d.join("log/munged.log").display()))
            .arg(format!("--seed-file={}", d.join("munged.seed").display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("starting munged");
        cluster.daemons.push(("munged", munged));
        cluster.wait_for("munged's socket", || socket.exists().then_some(()));
        let host = String::from_utf8(Command::new("hostname").arg("-s").output().unwrap().stdout).unwrap();
        let host = host.trim();
        let (ctld_port, d_port) = (free_port(), free_port());
        let conf = format!(
            "ClusterName=companiontest\n\
             SlurmctldHost={host}(127.0.0.1)\n\
             SlurmctldPort={ctld_port}\n\
             SlurmdPort={d_port}\n\
             AuthType=auth/munge\n\
             CredType=cred/munge\n\
             AuthInfo=socket={sock}\n\
             SlurmUser=root\n\
             SlurmdUser=root\n\
             StateSaveLocation={d}/state\n\
             SlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\n\
             SlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/log/slurmctld.log\n\
             SlurmdLogFile={d}/log/slurmd.log\n\
             ProctrackType=proctrack/linuxproc\n\
             TaskPlugin=task/none\n\
             SelectType=select/cons_tres\n\
             SelectTypeParameters=CR_CPU\n\
             ReturnToService=2\n\
             MpiDefault=none\n\
             MailProg=/bin/true\n\
             JobCompType=jobcomp/none\n\
             JobAcctGatherType=jobacct_gather/none\n\
             AccountingStorageType=accounting_storage/none\n\
             MinJobAge=3600\n\
             NodeName={node} NodeHostname={host} NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN\n\
             PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n",
            sock = socket.display(),
            d = d.display(),
            node = cluster.node,
        );
        std::fs::write(&cluster.conf, conf).unwrap();
        for (name, args) in [("slurmctld", vec!["-D"]), ("slurmd", vec!["-D", "-N", "companion1"])] {
            // In the cluster's folder: slurmd's slurmstepd inherit it (see `processes_in`).
            let child = Command::new(find(name).unwrap())
                .current_dir(&cluster.dir)
                .args(&args)
                .arg("-f")
                .arg(&cluster.conf)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap_or_else(|e| panic!("starting {name}: {e}"));
            cluster.daemons.push((name, child));
        }
        cluster.wait_for("the node to be idle (sinfo)", || {
            let o = cluster.slurm("sinfo", &["-h", "-n", "companion1", "-o", "%T"]);
            (String::from_utf8_lossy(&o.stdout).trim() == "idle").then_some(())
        });
        cluster
    }

    fn work(&self) -> PathBuf {
        self.dir.join("work")
    }

    /// A command with this cluster's configuration, in the work folder, `companion` on PATH.
    fn command(&self, program: &Path) -> Command {
        let bin = Path::new(BIN).parent().unwrap();
        let path = std::env::var_os("PATH").unwrap_or_default();
        let path =
            std::env::join_paths(std::iter::once(bin.to_path_buf()).chain(std::env::split_paths(&path)))
                .unwrap();
        let mut c = Command::new(program);
        c.current_dir(self.work()).env("SLURM_CONF", &self.conf).env("PATH", path);
        c
    }

    fn slurm(&self, program: &str, args: &[&str]) -> Output {
        self.command(&find(program).unwrap()).args(args).output().unwrap()
    }

    /// Runs one of the doc's shell blocks; its "array JOBID, merge MERGE" line.
    fn submit(&self, block: &str) -> (String, String) {
        let o = self
            .command(Path::new("bash"))
            .arg("-euo")
            .arg("pipefail")
            .arg("-c")
            .arg(block)
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout).to_string();
        assert!(
            o.status.success(),
            "the doc's block failed:\n{block}\n{out}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let line =
            out.lines().find_map(|l| l.strip_prefix("array ")).unwrap_or_else(|| panic!("no job ids: {out}"));
        let (array, merge) = line.split_once(", merge ").unwrap();
        (array.trim().to_string(), merge.trim().to_string())
    }

    /// `JobState` and `Reason` of each record `scontrol show job` gives for `id` (one per array
    /// task once it has started), by `ArrayTaskId` (or the job id).
    fn jobs(&self, id: &str) -> BTreeMap<String, (String, String)> {
        let o = self.slurm("scontrol", &["-o", "show", "job", id]);
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(|l| {
                let field = |k: &str| {
                    l.split(' ').find_map(|w| w.strip_prefix(k).map(str::to_string)).unwrap_or_default()
                };
                let task = field("ArrayTaskId=");
                let key = if task.is_empty() { field("JobId=") } else { task };
                (key, (field("JobState="), field("Reason=")))
            })
            .collect()
    }

    /// Polls `f` until it gives a value; past the watchdog, fails naming `what`.
    fn wait_for<T>(&self, what: &str, mut f: impl FnMut() -> Option<T>) -> T {
        loop {
            if let Some(v) = f() {
                return v;
            }
            assert!(Instant::now() < self.deadline, "watchdog ({WATCHDOG_S} s): still waiting for {what}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Waits until job `id`'s records (all tasks) are in a final state; the states by task.
    fn wait_ended(&self, id: &str) -> BTreeMap<String, (String, String)> {
        self.wait_for(&format!("job {id} to end"), || {
            let jobs = self.jobs(id);
            let ended = !jobs.is_empty()
                && jobs.values().all(|(s, _)| {
                    !matches!(s.as_str(), "PENDING" | "RUNNING" | "SUSPENDED" | "COMPLETING" | "CONFIGURING")
                });
            ended.then_some(jobs)
        })
    }
}

/// The pids of the live processes, other than this one, with their working folder or an open
/// file in `dir` (from /proc): slurmd's slurmstepd keep its log open, the jobs run in `work`.
fn processes_in(dir: &Path) -> Vec<u32> {
    let inside = |link: PathBuf| link.starts_with(dir);
    let Ok(procs) = std::fs::read_dir("/proc") else { return Vec::new() };
    procs
        .filter_map(Result::ok)
        .filter_map(|e| e.file_name().to_str().and_then(|n| n.parse::<u32>().ok()))
        .filter(|pid| *pid != std::process::id())
        .filter(|pid| {
            std::fs::read_link(format!("/proc/{pid}/cwd")).is_ok_and(inside)
                || std::fs::read_dir(format!("/proc/{pid}/fd")).is_ok_and(|fds| {
                    fds.filter_map(Result::ok).any(|fd| std::fs::read_link(fd.path()).is_ok_and(inside))
                })
        })
        .collect()
}

/// The parent of process `pid` (from /proc).
fn parent(pid: u32) -> Option<u32> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // "pid (comm) state ppid …"; comm may hold spaces and parentheses.
    stat.rsplit_once(')')?.1.split_whitespace().nth(1)?.parse().ok()
}

fn set_mode(path: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
}

impl Drop for Cluster {
    fn drop(&mut self) {
        if self.daemons.iter().any(|(n, _)| *n == "slurmctld") {
            let _ = self.slurm("scancel", &["--user=root"]);
            // Bounded: the jobs' processes end before slurmd does.
            let until = Instant::now() + Duration::from_secs(60);
            while Instant::now() < until {
                let o = self.slurm("squeue", &["-h", "-o", "%i"]);
                if !o.status.success() || o.stdout.iter().all(u8::is_ascii_whitespace) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        }
        // In reverse order of starting: slurmd, slurmctld, munged.
        while let Some((name, mut child)) = self.daemons.pop() {
            let _ = Command::new("kill").arg("-TERM").arg(child.id().to_string()).status();
            let until = Instant::now() + Duration::from_secs(30);
            while Instant::now() < until && matches!(child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(50));
            }
            if matches!(child.try_wait(), Ok(None)) {
                eprintln!("{name} did not stop on SIGTERM; killing it");
                let _ = child.kill();
                let _ = child.wait();
            }
            if name == "slurmd" {
                // Its slurmstepd (and any job process) outlive it briefly: wait for them, bounded.
                let daemons: Vec<u32> = self.daemons.iter().map(|(_, c)| c.id()).collect();
                // (slurmctld's own child, slurmscriptd, ends with it.)
                let others = || -> Vec<u32> {
                    let ours =
                        |p: &u32| daemons.contains(p) || parent(*p).is_some_and(|pp| daemons.contains(&pp));
                    processes_in(&self.dir).into_iter().filter(|p| !ours(p)).collect()
                };
                let until = Instant::now() + Duration::from_secs(60);
                while Instant::now() < until && !others().is_empty() {
                    std::thread::sleep(Duration::from_millis(50));
                }
                let left = others();
                for pid in left {
                    let cmd = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
                    eprintln!(
                        "a process of the test's cluster still alive after 60 s (left alone): {pid} {}",
                        String::from_utf8_lossy(&cmd).replace('\0', " ")
                    );
                }
            }
        }
        if std::thread::panicking() {
            eprintln!(
                "the cluster's folder, with the daemons' and jobs' logs, is kept: {}",
                self.dir.display()
            );
            for log in ["log/slurmctld.log", "log/slurmd.log"] {
                let text = std::fs::read_to_string(self.dir.join(log)).unwrap_or_default();
                let tail: Vec<&str> = text.lines().rev().take(15).collect();
                eprintln!("--- {log} (last lines)");
                for l in tail.iter().rev() {
                    eprintln!("{l}");
                }
            }
        } else {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// The fenced block after the line `<!-- slurm: NAME -->` of docs/book/src/explore-tune.md.
fn doc_block(doc: &str, name: &str) -> String {
    let marker = format!("<!-- slurm: {name} -->");
    let rest = doc.split_once(&marker).unwrap_or_else(|| panic!("the explore chapter has no {marker}")).1;
    let body =
        rest.trim_start().strip_prefix("```sh\n").unwrap_or_else(|| panic!("no ```sh block after {marker}"));
    body.split_once("\n```").unwrap().0.to_string() + "\n"
}

/// `from` replaced by `to` in `text`, where it must occur exactly once.
fn replace_once(text: &str, from: &str, to: &str) -> String {
    assert_eq!(text.matches(from).count(), 1, "the doc's script must contain {from:?} once");
    text.replacen(from, to, 1)
}

/// The files of a folder and their bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .map(|p| (p.file_name().unwrap().to_string_lossy().to_string(), std::fs::read(&p).unwrap()))
        .collect()
}

fn sample_lines(path: &Path) -> usize {
    std::fs::read_to_string(path)
        .map(|t| t.lines().skip(1).filter(|l| l.ends_with(|c: char| c.is_ascii_hexdigit())).count())
        .unwrap_or(0)
}

#[test]
fn the_documented_job_array_merges_to_the_unsharded_run_with_a_cancelled_and_rerun_task() {
    if let Some(why) = unavailable() {
        assert!(
            std::env::var_os("COMPANION_REQUIRE_SLURM").is_none(),
            "COMPANION_REQUIRE_SLURM is set but the Slurm test cannot run: {why}"
        );
        eprintln!("skipped: the Slurm job-array test cannot run here: {why}");
        return;
    }
    let doc = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/book/src/explore-tune.md"),
    )
    .unwrap();
    let script = doc_block(&doc, "script");
    let script = replace_once(&script, "--array=1-16", &format!("--array=1-{SHARDS}"));
    let script = replace_once(&script, "N=16", &format!("N={SHARDS}"));
    let script = replace_once(&script, "--cpus-per-task=4", "--cpus-per-task=1");
    let script = replace_once(&script, "--samples 100000", &format!("--samples {SAMPLES}"));
    let (submit, rerun) = (doc_block(&doc, "submit"), doc_block(&doc, "rerun"));
    // The sweep's own flags, as the script gives them (to run it unsharded and by hand).
    let flags = |shard: Option<u64>, out: &str| -> Vec<String> {
        let mut a: Vec<String> = "explore --platform car --limits realistic --trajectory 1 --choice c --seed 7 --threads 1 --quiet"
            .split(' ')
            .map(String::from)
            .collect();
        a.extend(["--samples".into(), SAMPLES.to_string(), "--out".into(), out.into()]);
        if let Some(k) = shard {
            a.extend(["--shard".into(), format!("{k}/{SHARDS}")]);
        }
        a
    };
    assert!(script.contains("--platform car --limits realistic --trajectory 1 --choice c"), "{script}");

    let cluster = Cluster::start(Instant::now() + Duration::from_secs(WATCHDOG_S));
    let work = cluster.work();
    std::fs::write(work.join("explore.sbatch"), &script).unwrap();

    // The unsharded run, directly.
    let reference = cluster.command(Path::new(BIN)).args(flags(None, "unsharded")).output().unwrap();
    assert!(reference.status.success(), "{}", String::from_utf8_lossy(&reference.stderr));

    let (array, first_merge) = cluster.submit(&submit);
    // Task 2 caught mid-shard: a sample in its journal, no results yet; frozen (suspended).
    let shard2 = work.join("shards/2");
    cluster.wait_for("shard 2's first journal line", || {
        (sample_lines(&shard2.join("journal.csv")) > 0).then_some(())
    });
    let task2 = format!("{array}_2");
    let o = cluster.slurm("scontrol", &["suspend", &task2]);
    assert!(o.status.success(), "scontrol suspend: {}", String::from_utf8_lossy(&o.stderr));
    cluster.wait_for("task 2 suspended", || {
        (cluster.jobs(&task2).values().any(|(s, _)| s == "SUSPENDED")).then_some(())
    });
    assert!(
        !shard2.join("results.csv").exists(),
        "shard 2 finished before it could be suspended: raise SAMPLES so that a shard takes longer"
    );
    // A second process on its folder is refused at once, leaving the journal as it was.
    let journal = std::fs::read(shard2.join("journal.csv")).unwrap();
    let second = cluster.command(Path::new(BIN)).args(flags(Some(2), "shards/2")).output().unwrap();
    let err = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(9), "a second process on shards/2: {err}");
    assert!(err.contains("another process is running this exploration in shards/2"), "{err}");
    assert!(
        std::fs::read(shard2.join("journal.csv")).unwrap() == journal,
        "the refused process touched the journal"
    );
    // Merge calls it running (asked about shard 2 alone: the others may be starting).
    let m = cluster
        .command(Path::new(BIN))
        .args(["explore", "merge", "shards/2", "--out", "probe"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(!m.status.success() && err.contains("still running"), "{err}");
    assert!(!err.contains("run its command again"), "{err}");

    // Cancelled: the afterok merge is cancelled by Slurm, never left pending.
    let o = cluster.slurm("scancel", &[&task2]);
    assert!(o.status.success(), "scancel: {}", String::from_utf8_lossy(&o.stderr));
    let tasks = cluster.wait_ended(&array);
    let merge_state = cluster.wait_ended(&first_merge);
    assert_eq!(
        merge_state.values().next().map(|(s, r)| (s.as_str(), r.as_str())),
        Some(("CANCELLED", "DependencyNeverSatisfied")),
        "the first merge"
    );
    for k in 1..=SHARDS {
        let want = if k == 2 { "CANCELLED" } else { "COMPLETED" };
        assert_eq!(tasks.get(&k.to_string()).map(|(s, _)| s.as_str()), Some(want), "task {k}: {tasks:?}");
    }
    let kept = sample_lines(&shard2.join("journal.csv"));
    assert!(kept > 0 && !shard2.join("results.csv").exists(), "shard 2 after the cancel");
    let m = cluster
        .command(Path::new(BIN))
        .args(["explore", "merge", "shards/1", "shards/2", "shards/3", "shards/4", "--out", "probe"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(
        err.contains(&format!("shard 2/{SHARDS} is unfinished and no process is running it ({kept} of its")),
        "{err}"
    );

    // The doc's rerun: task 2 alone, resumed from its journal, then the merge.
    assert!(rerun.contains("--array=2 explore.sbatch"), "the doc's rerun must rerun task 2: {rerun}");
    let (again, merge) = cluster.submit(&rerun);
    let tasks = cluster.wait_ended(&again);
    assert!(tasks.values().all(|(s, _)| s == "COMPLETED"), "the rerun: {tasks:?}");
    let log = std::fs::read_to_string(work.join("logs/explore-2.out")).unwrap();
    assert!(log.contains(&format!("({kept} resumed from the journal)")), "{log}");
    let merged = cluster.wait_ended(&merge);
    assert!(merged.values().all(|(s, _)| s == "COMPLETED"), "the merge: {merged:?}");

    let (want, got) = (files(&work.join("unsharded")), files(&work.join("explore-car-c")));
    assert_eq!(got.keys().collect::<Vec<_>>(), want.keys().collect::<Vec<_>>(), "the merge's files");
    for (name, bytes) in &got {
        assert!(*bytes == want[name], "{name}: the merge differs from the unsharded run");
    }
    eprintln!(
        "merged {} files of {SAMPLES} samples from {SHARDS} Slurm tasks, equal to the unsharded run",
        got.len()
    );
}
