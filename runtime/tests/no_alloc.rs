//! The HIL cycle allocates nothing of its own: a counting global allocator around (1) both
//! loops of the demo over real iceoryx2 endpoints in real time, counting everything but what
//! happens inside the transport's calls (iceoryx2's own allocations are its business and are
//! not pinned here), and (2) the plant's real-time loop and (3) the controller's serve loop
//! over in-process links on a fake clock, where nothing at all may allocate.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::collections::VecDeque;
use std::time::Duration;

use anyhow::Result;
use companion_core::{PaperRun, PlatformKind};
use companion_plant::{PaperTrajectory, Simulated};
use companion_runtime::domain::controller::AnyController;
use companion_runtime::domain::record::Row;
use companion_runtime::domain::scenario::Scenario;
use companion_runtime::run::hil::messages::{answer, Stamp};
use companion_runtime::run::hil::plant_loop::{run_real_time, PlantSide};
use companion_runtime::run::hil::serve::{serve, serve_law, ServeOptions};
use companion_runtime::run::hil::stats::{ControlStats, LiveFigures, PlantStats};
use companion_runtime::run::hil::{ControlEnd, Timing, WaitMode};
use companion_runtime::run::robot::Robot;
use companion_runtime::sys::clock::{Clock, FakeClock, MonotonicClock};
use companion_runtime::sys::lock::DemoName;
use companion_runtime::transport::ipc::{ControlEndpoint, PlantEndpoint};
use companion_runtime::transport::link::{Link, LinkError, PeerState};
use companion_runtime::transport::wire::{
    flags, platform, CommandHeader, CommandMsg, ControllerIdentity, LoggedDiagnostics, MeasurementHeader,
    MeasurementMsg,
};

struct Counting;

/// Allocations by every thread of the process (Zenoh receives on threads of its own).
static ALL_THREADS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

thread_local! {
    // Per thread: the tests run in parallel.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    static TRANSPORT_COUNTING: Cell<bool> = const { Cell::new(false) };
    static TRANSPORT: Cell<u64> = const { Cell::new(0) };
}

fn count_one() {
    ALL_THREADS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    if COUNTING.with(Cell::get) {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
    }
    if TRANSPORT_COUNTING.with(Cell::get) {
        TRANSPORT.with(|n| n.set(n.get() + 1));
    }
}

// SAFETY: delegates every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: the caller's contract is passed through.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by this thread while `f` runs.
fn allocations_in<T>(f: impl FnOnce() -> T) -> (u64, T) {
    let before = ALLOCATIONS.with(Cell::get);
    COUNTING.with(|c| c.set(true));
    let r = f();
    COUNTING.with(|c| c.set(false));
    (ALLOCATIONS.with(Cell::get) - before, r)
}

/// The HIL demo's timing: 1 kHz, 500 µs deadline, spin.
const TIMING: Timing = Timing {
    period_ns: 1_000_000,
    deadline_ns: 500_000,
    hold_periods: 20,
    wait: WaitMode::Spin,
    release: companion_runtime::run::hil::ReleaseTimer::Sleep,
    spin_margin_ns: 100_000,
    silence_ns: 20_000_000,
    peer_timeout_ns: 2_000_000_000,
    lockstep: false,
    max_command_age: 0,
};

/// The HIL demo's scenario: trajectory 1, run (a), unicycle, `duration` s.
fn scenario(duration: f64) -> Scenario {
    Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
        .duration(duration)
        .build()
        .unwrap()
}

/// The command header of a controller of the paper's unicycle.
fn command_header() -> CommandHeader {
    let identity = ControllerIdentity {
        platform: platform::UNICYCLE,
        joint_count: 3,
        space: companion_runtime::transport::wire::target::space::PLANAR,
        arm_hash: 0,
        scenario_hash: 0,
        max_dt: 0.01,
    };
    CommandHeader { identity, flags: 0, received_ns: 0, skipped: 0, delay: 0.0 }
}

fn measurement(seq: u64, fl: u32) -> MeasurementMsg {
    let s = scenario(30.0);
    let plant = companion_runtime::run::sim::build_plant(&s).unwrap();
    let header = MeasurementHeader {
        seq,
        flags: fl,
        session: 9,
        dt: 1e-3,
        platform: platform::UNICYCLE,
        hold_periods: TIMING.hold_periods,
        period_ns: TIMING.period_ns,
        ..MeasurementHeader::default()
    };
    MeasurementMsg::new(header, &plant.measure())
}

/// A link decorator that stops counting while the transport works: what is counted is the
/// loop's own allocations, whatever iceoryx2 does inside `send`, `receive` or the node list
/// (its internals are its own business and change between versions).
struct Uncounted<L> {
    inner: L,
    /// Allocations the transport made (reported, not asserted).
    transport: u64,
}

impl<L> Uncounted<L> {
    fn pause<T>(&mut self, f: impl FnOnce(&mut L) -> T) -> T {
        let was = COUNTING.with(|c| c.replace(false));
        let before = TRANSPORT.with(Cell::get);
        TRANSPORT_COUNTING.with(|c| c.set(true));
        let r = f(&mut self.inner);
        TRANSPORT_COUNTING.with(|c| c.set(false));
        self.transport += TRANSPORT.with(Cell::get) - before;
        COUNTING.with(|c| c.set(was));
        r
    }
}

impl<L: Link> Link for Uncounted<L> {
    type Tx = L::Tx;
    type Rx = L::Rx;
    fn publish(&mut self, m: &L::Tx) -> Result<(), LinkError> {
        self.pause(|l| l.publish(m))
    }
    fn try_receive(&mut self) -> Result<Option<L::Rx>, LinkError> {
        self.pause(Link::try_receive)
    }
    fn wait_event(&mut self, d: Duration) -> Result<(), LinkError> {
        self.pause(|l| l.wait_event(d))
    }
    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        self.pause(Link::peer_state)
    }
}

#[test]
fn the_counter_counts() {
    let (n, v) = allocations_in(|| Vec::<u8>::with_capacity(10));
    assert_eq!(n, 1);
    drop(v);
    let mut l =
        Uncounted { inner: Script { inbox: VecDeque::new(), sent: Vec::new(), ready: true }, transport: 0 };
    let c = CommandMsg::answer::<3>(
        &measurement(0, 0),
        &command_header(),
        &companion_core::Command::zero(),
        None,
        &DIAG,
    );
    // `sent` grows inside the transport: not ours, counted apart.
    let (n, ()) = allocations_in(|| l.publish(&c).unwrap());
    assert_eq!((n, l.transport), (0, 1));
}

const DIAG: LoggedDiagnostics = LoggedDiagnostics::IDLE;

/// The two loops of the HIL demo, as the processes run them (real clock, real iceoryx2
/// endpoints, adaptive waiting), in two threads of this process, for `duration` seconds at
/// 1 kHz: the allocations of the plant's loop and of the controller's (each less the
/// transport's own), and the controller's answers.
fn real_time_allocations(duration: f64) -> (u64, u64, u64) {
    let name = DemoName::new(&format!("noalloc-{}-{:.0}", std::process::id(), duration * 1000.0)).unwrap();
    let timing = Timing { wait: WaitMode::Adaptive, ..TIMING };
    let s = scenario(duration);
    let steps = s.steps();
    let plant_side = {
        let (name, s) = (name.clone(), s.clone());
        std::thread::spawn(move || {
            let ep = PlantEndpoint::plant(&name, true).unwrap();
            ep.wait_for_peer(Duration::from_secs(20), || None).unwrap();
            let mut plant = companion_runtime::run::sim::build_plant(&s).unwrap();
            let mut link = Uncounted { inner: ep, transport: 0 };
            let mut stats = PlantStats::default();
            let live = LiveFigures::default();
            let mut rows: Vec<Row> = Vec::with_capacity(2_100);
            let mut sink = |_: u64, r: &Row, _: bool| {
                rows.push(*r);
                true
            };
            let stamp = Stamp {
                session: 5,
                scenario_hash: companion_runtime::run::hil::handshake::controller_hash(&s.controller),
                arm_hash: companion_runtime::run::hil::handshake::arm_hash(),
                period_ns: timing.period_ns,
                dt: s.dt,
                flags: 0,
                platform: platform::UNICYCLE,
                hold_periods: timing.hold_periods,
            };
            let (n, end) = allocations_in(|| {
                let mut side = PlantSide {
                    clock: &MonotonicClock,
                    link: &mut link,
                    timing,
                    stamp,
                    stats: &mut stats,
                    live: &live,
                    last_sent: None,
                };
                let star = companion_core::Pose::new(0.5, 0.0, 0.0);
                let mut robot = Robot { plant: &mut plant, target_in_effector: star };
                run_real_time(&mut side, &mut robot, steps, &mut sink)
            });
            (n, end.unwrap(), stats.cycles, stats.fresh, link.transport)
        })
    };
    let ep = ControlEndpoint::control(&name, true).unwrap();
    ep.wait_for_peer(Duration::from_secs(20), || None).unwrap();
    let mut link = Uncounted { inner: ep, transport: 0 };
    let opt = ServeOptions {
        wait: WaitMode::Adaptive,
        spin_margin_ns: 0,
        silence_ns: 20_000_000,
        peer_timeout_ns: 2_000_000_000,
        startup_timeout_ns: 20_000_000_000,
        forward_interrupt: false,
        delay_compensation: true,
        deadline_ns: 500_000,
    };
    let mut stats = ControlStats::default();
    let silent = companion_runtime::domain::observe::Silent;
    let (n_control, end) =
        allocations_in(|| serve(&MonotonicClock, &mut link, &s.controller, &opt, &mut stats, &silent));
    let (n_plant, plant_end, cycles, fresh, plant_transport) = plant_side.join().unwrap();
    println!(
        "{cycles} periods, {fresh} fresh commands; the transport allocated {plant_transport} times in the plant, {} \
         in the controller (not ours)",
        link.transport
    );
    assert_eq!(plant_end, companion_runtime::run::hil::PlantEnd::Completed);
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(cycles, steps + 1);
    assert!(stats.answered > steps / 2, "{} answers", stats.answered);
    (n_plant, n_control, stats.answered)
}

#[test]
fn the_real_time_loops_over_iceoryx2_allocate_nothing_of_their_own() {
    // The plant's loop allocates nothing at all. The controller's allocates only at the
    // handshake (its identity's hash, the law built for the plant it meets): a run of 2 000
    // periods allocates exactly what a run of 500 does.
    let (short_plant, short_control, short_answers) = real_time_allocations(0.5);
    let (n_plant, n_control, answers) = real_time_allocations(2.0);
    assert_eq!(short_plant, 0, "the plant's loop allocated {short_plant} times");
    assert_eq!(n_plant, 0, "the plant's loop allocated {n_plant} times");
    assert!(short_control > 0, "the handshake builds the law");
    assert_eq!(
        n_control, short_control,
        "the controller's loop allocated {n_control} times in {answers} answers, {short_control} in {short_answers}"
    );
}

/// The Zenoh exchange (feature `zenoh`), measured rather than assumed: receiving is a pop from
/// the preallocated ring (nothing), but Zenoh allocates to publish and, on its own threads,
/// to deliver. The counts asserted are the ones measured with zenoh 1.10 (a change in them is
/// a change worth seeing).
#[cfg(feature = "zenoh")]
#[test]
fn the_zenoh_exchange_allocates_only_in_zenoh() {
    use std::sync::atomic::Ordering;

    use companion_runtime::sys::lock::Role;
    use companion_runtime::transport::zenoh_link::{
        Security, TcpEndpoint, ZenohControl, ZenohLink, ZenohPlant,
    };

    let name = DemoName::new(&format!("noalloc-zenoh-{}", std::process::id())).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let ep = TcpEndpoint::parse(&format!("tcp/127.0.0.1:{port}")).unwrap();
    let mut plant = ZenohPlant::open(
        &name,
        Role::Plant,
        ZenohLink::Listen(ep.clone()),
        &Security::Insecure,
        Duration::from_secs(2),
    )
    .unwrap();
    let mut control = ZenohControl::open(
        &name,
        Role::Control,
        ZenohLink::Connect(ep),
        &Security::Insecure,
        Duration::from_secs(2),
    )
    .unwrap();
    plant.wait_for_peer(Duration::from_secs(10), || None).unwrap();
    control.wait_for_peer(Duration::from_secs(10), || None).unwrap();
    let m = measurement(0, 0);
    let diag = LoggedDiagnostics::IDLE;
    let c = CommandMsg::answer::<3>(&m, &command_header(), &companion_core::Command::zero(), None, &diag);
    let wait = |f: &mut dyn FnMut() -> bool| {
        let end = std::time::Instant::now() + Duration::from_secs(5);
        while !f() {
            assert!(std::time::Instant::now() < end, "no message within 5 s");
            std::thread::yield_now();
        }
    };
    let cycle = |plant: &mut ZenohPlant, control: &mut ZenohControl| -> (u64, u64, u64, u64) {
        let (a, ()) = allocations_in(|| plant.send(&m).unwrap());
        let mut got = None;
        let mut b = 0;
        wait(&mut || {
            let (k, r) = allocations_in(|| control.try_receive());
            b += k;
            got = r;
            got.is_some()
        });
        let (d, ()) = allocations_in(|| control.send(&c).unwrap());
        let mut e = 0;
        wait(&mut || {
            let (k, r) = allocations_in(|| plant.try_receive());
            e += k;
            r.is_some()
        });
        (a, b, d, e)
    };
    for _ in 0..500 {
        cycle(&mut plant, &mut control);
    }
    let n = 5_000u64;
    let before = ALL_THREADS.load(Ordering::Relaxed);
    let mut own = (0, 0, 0, 0);
    for _ in 0..n {
        let (a, b, d, e) = cycle(&mut plant, &mut control);
        own = (own.0 + a, own.1 + b, own.2 + d, own.3 + e);
    }
    let all = ALL_THREADS.load(Ordering::Relaxed) - before;
    println!(
        "zenoh, per exchange of one measurement and one command: publish {} + {}, receive {} + {} \
         allocations on the loop's thread; {:.1} in the whole process (Zenoh's threads included)",
        own.0 as f64 / n as f64,
        own.2 as f64 / n as f64,
        own.1 as f64 / n as f64,
        own.3 as f64 / n as f64,
        all as f64 / n as f64
    );
    assert_eq!((own.1, own.3), (0, 0), "receiving is a ring pop");
    // zenoh 1.10's `put`: two allocations (the payload's buffer and its shared handle).
    assert_eq!((own.0, own.2), (2 * n, 2 * n), "allocations of the two publications");
    assert_eq!(plant.malformed() + control.malformed(), 0);
}

/// A link whose controller answers at once, in process: `answer` turns a measurement into the
/// command.
struct InstantController<F> {
    answer: F,
    pending: Option<CommandMsg>,
    clock: std::rc::Rc<FakeClock>,
}

impl<F: FnMut(&MeasurementMsg) -> CommandMsg> Link for InstantController<F> {
    type Tx = MeasurementMsg;
    type Rx = CommandMsg;
    fn publish(&mut self, m: &MeasurementMsg) -> Result<(), LinkError> {
        let mut c = (self.answer)(m);
        c.compute_ns = 3_000;
        self.clock.advance(10_000);
        self.pending = Some(c);
        Ok(())
    }
    fn try_receive(&mut self) -> Result<Option<CommandMsg>, LinkError> {
        Ok(self.pending.take())
    }
    fn wait_event(&mut self, _: Duration) -> Result<(), LinkError> {
        Ok(())
    }
    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        Ok(PeerState::Alive(1))
    }
}

#[test]
fn the_plant_loop_allocates_nothing() {
    let s = scenario(5.0);
    let mut plant = companion_runtime::run::sim::build_plant(&s).unwrap();
    let clock = std::rc::Rc::new(FakeClock::new(1_000_000_000, 100));
    let mut ctrl = AnyController::new(&s.controller).unwrap();
    let answer_of = |m: &MeasurementMsg| {
        let r = ctrl.step(&m.measurement::<3>().unwrap(), m.dt, 0.0);
        answer(m, &command_header(), &r)
    };
    let mut link = InstantController { answer: answer_of, pending: None, clock: clock.clone() };
    let mut stats = PlantStats::default();
    let live = LiveFigures::default();
    let mut rows: Vec<Row> = Vec::with_capacity(6_000);
    let mut sink = |_: u64, r: &Row, _: bool| {
        rows.push(*r);
        true
    };
    let stamp = Stamp {
        session: 1,
        scenario_hash: 0,
        arm_hash: 0,
        period_ns: TIMING.period_ns,
        dt: s.dt,
        flags: 0,
        platform: platform::UNICYCLE,
        hold_periods: TIMING.hold_periods,
    };
    let steps = s.steps();
    let (n, end) = allocations_in(|| {
        let mut side = PlantSide {
            clock: clock.as_ref(),
            link: &mut link,
            timing: TIMING,
            stamp,
            stats: &mut stats,
            live: &live,
            last_sent: None,
        };
        let mut robot =
            Robot { plant: &mut plant, target_in_effector: companion_core::Pose::new(0.5, 0.0, 0.0) };
        run_real_time(&mut side, &mut robot, steps, &mut sink)
    });
    assert_eq!(n, 0, "{n} allocations in {} plant cycles", stats.cycles);
    assert!(end.is_ok());
    assert_eq!(stats.cycles, 5_001);
    assert_eq!(stats.deadline_misses, 0);
    assert_eq!(rows.len(), 5_001);
    assert!(clock.now_ns() > 1_000_000_000 + 4_999_000_000);
}

/// A plant that sends its next measurement once the previous one is answered.
struct Script {
    inbox: VecDeque<MeasurementMsg>,
    sent: Vec<CommandMsg>,
    ready: bool,
}

impl Link for Script {
    type Tx = CommandMsg;
    type Rx = MeasurementMsg;
    fn publish(&mut self, c: &CommandMsg) -> Result<(), LinkError> {
        self.sent.push(*c);
        self.ready = true;
        Ok(())
    }
    fn try_receive(&mut self) -> Result<Option<MeasurementMsg>, LinkError> {
        if !self.ready {
            return Ok(None);
        }
        self.ready = false;
        Ok(self.inbox.pop_front())
    }
    fn wait_event(&mut self, _: Duration) -> Result<(), LinkError> {
        Ok(())
    }
    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        Ok(PeerState::Alive(1))
    }
}

/// Allocations of one `serve` over measurements `0..=last` (the last one ends the run).
fn serve_allocations(s: &Scenario, last: u64) -> u64 {
    let m = measurement(0, 0);
    let mut inbox = VecDeque::with_capacity(5_001);
    for seq in 0..last {
        inbox.push_back(MeasurementMsg { seq, plant_time_ns: seq * 1_000_000, ..m });
    }
    inbox.push_back(MeasurementMsg {
        seq: last,
        flags: flags::END_OF_RUN,
        plant_time_ns: last * 1_000_000,
        ..m
    });
    let mut link = Script { inbox, sent: Vec::with_capacity(5_001), ready: true };
    let opt = ServeOptions {
        wait: WaitMode::Spin,
        spin_margin_ns: 0,
        silence_ns: 20_000_000,
        peer_timeout_ns: 2_000_000_000,
        startup_timeout_ns: 2_000_000_000,
        forward_interrupt: false,
        delay_compensation: true,
        deadline_ns: 500_000,
    };
    let clock = FakeClock::new(0, 100);
    let mut stats = ControlStats::default();
    let silent = companion_runtime::domain::observe::Silent;
    let (n, end) = allocations_in(|| serve(&clock, &mut link, &s.controller, &opt, &mut stats, &silent));
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(link.sent.len() as u64, last + 1);
    n
}

#[test]
fn the_controller_loop_allocates_nothing() {
    let s = scenario(30.0);
    // The handshake builds the law (a few allocations, once); the cycles after it none.
    let handshake = serve_allocations(&s, 1);
    let long = serve_allocations(&s, 5_000);
    assert_eq!(
        long,
        handshake,
        "{} allocations in 4 999 controller cycles after the handshake",
        long - handshake
    );
    assert!(handshake > 0, "the law is built at the handshake");
}

/// A spatial scenario: the UR5 on the unicycle, lifted trajectory 1.
fn ur5_scenario(duration: f64) -> companion_runtime::run::spatial::SpatialScenario {
    use companion_runtime::domain::arm::{ArmChoice, SpatialArmSpec};
    use companion_runtime::run::spatial::{SpatialScenario, SpatialTargetChoice};
    let arm = SpatialArmSpec::from_choice(&ArmChoice::parse("ur5")).unwrap().unwrap();
    SpatialScenario::new(scenario(duration), arm, SpatialTargetChoice::Lifted(PaperTrajectory::One)).unwrap()
}

/// The real-time loop with a spatial arm (§5): the UR5's plant, its rows the spatial records.
#[test]
fn the_plant_loop_of_a_spatial_arm_allocates_nothing() {
    type SpatialRow = Row<companion_core::Spatial, 6>;
    let ss = ur5_scenario(3.0);
    let star = companion_runtime::run::spatial::target_in_effector::<6>(&ss).unwrap();
    let chain = ss.arm.chain::<f64, 6>().unwrap();
    let mut plant = companion_runtime::run::spatial::build_plant(&ss, &chain, &star).unwrap();
    let clock = std::rc::Rc::new(FakeClock::new(1_000_000_000, 100));
    let mut ctrl =
        companion_runtime::domain::controller::boxed_spatial_controller::<6>(&ss.base.controller, &ss.arm)
            .unwrap();
    let answer_of = |m: &MeasurementMsg| {
        let r = ctrl.step(&m.read::<6, companion_core::Spatial>().unwrap(), m.dt, m.delay);
        answer(m, &command_header(), &r)
    };
    let mut link = InstantController { answer: answer_of, pending: None, clock: clock.clone() };
    let mut stats = PlantStats::default();
    let live = LiveFigures::default();
    let mut rows: Vec<SpatialRow> = Vec::with_capacity(3_100);
    let mut sink = |_: u64, r: &SpatialRow, _: bool| {
        rows.push(*r);
        true
    };
    let stamp = Stamp {
        session: 1,
        scenario_hash: 0,
        arm_hash: 0,
        period_ns: TIMING.period_ns,
        dt: ss.base.dt,
        flags: 0,
        platform: platform::UNICYCLE,
        hold_periods: TIMING.hold_periods,
    };
    let steps = ss.steps();
    let (n, end) = allocations_in(|| {
        let mut side = PlantSide {
            clock: clock.as_ref(),
            link: &mut link,
            timing: TIMING,
            stamp,
            stats: &mut stats,
            live: &live,
            last_sent: None,
        };
        let mut robot = Robot { plant: &mut plant, target_in_effector: star };
        run_real_time(&mut side, &mut robot, steps, &mut sink)
    });
    assert_eq!(n, 0, "{n} allocations in {} plant cycles", stats.cycles);
    assert_eq!(end.unwrap(), companion_runtime::run::hil::PlantEnd::Completed);
    assert_eq!((stats.cycles, stats.fresh, stats.deadline_misses), (3_001, 3_001, 0));
    assert_eq!(rows.len(), 3_001);
    // The arm followed the commands: the tracking error fell from the start.
    assert!(
        rows[3_000].plant.ep_norm < 0.5 * rows[0].plant.ep_norm.max(1e-3),
        "{} → {}",
        rows[0].plant.ep_norm,
        rows[3_000].plant.ep_norm
    );
}

/// The controller's loop serving a spatial arm allocates nothing after the handshake.
#[test]
fn the_controller_loop_of_a_spatial_arm_allocates_nothing() {
    use companion_runtime::run::hil::law::SpatialLaw;
    let ss = ur5_scenario(30.0);
    let chain = ss.arm.chain::<f64, 6>().unwrap();
    let arm_hash = companion_runtime::transport::wire::canonical::arm_hash(&chain);
    let star = companion_runtime::run::spatial::target_in_effector::<6>(&ss).unwrap();
    let plant = companion_runtime::run::spatial::build_plant(&ss, &chain, &star).unwrap();
    let header = MeasurementHeader {
        session: 9,
        arm_hash,
        scenario_hash: companion_runtime::run::hil::handshake::controller_hash(&ss.base.controller),
        dt: 1e-3,
        platform: platform::UNICYCLE,
        hold_periods: TIMING.hold_periods,
        period_ns: TIMING.period_ns,
        ..MeasurementHeader::default()
    };
    let m = MeasurementMsg::new(header, &plant.measure());
    let law = SpatialLaw { spec: &ss.base.controller, arm: &ss.arm, arm_hash };
    let (handshake, long) =
        (spatial_serve_allocations(&m, &law, 1), spatial_serve_allocations(&m, &law, 5_000));
    assert_eq!(
        long,
        handshake,
        "{} allocations in 4 999 controller cycles after the handshake",
        long - handshake
    );
    assert!(handshake > 0, "the law is built at the handshake");
}

/// Allocations of one `serve_law` of `law` over copies of `m` numbered `0..=last`.
fn spatial_serve_allocations(
    m: &MeasurementMsg,
    law: &companion_runtime::run::hil::law::SpatialLaw<'_>,
    last: u64,
) -> u64 {
    let mut inbox = VecDeque::with_capacity(5_001);
    for seq in 0..=last {
        let mut x = *m;
        x.seq = seq;
        x.plant_time_ns = seq * 1_000_000;
        if seq == last {
            x.flags = flags::END_OF_RUN;
        }
        inbox.push_back(x);
    }
    let mut link = Script { inbox, sent: Vec::with_capacity(5_001), ready: true };
    let opt = ServeOptions {
        wait: WaitMode::Spin,
        spin_margin_ns: 0,
        silence_ns: 20_000_000,
        peer_timeout_ns: 2_000_000_000,
        startup_timeout_ns: 2_000_000_000,
        forward_interrupt: false,
        delay_compensation: true,
        deadline_ns: 500_000,
    };
    let clock = FakeClock::new(0, 100);
    let mut stats = ControlStats::default();
    let silent = companion_runtime::domain::observe::Silent;
    let (n, end) =
        allocations_in(|| serve_law::<_, _, 6, _>(&clock, &mut link, law, &opt, &mut stats, &silent));
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(link.sent.len() as u64, last + 1);
    assert_eq!(stats.rejected, 0, "every step accepted");
    n
}

/// A sink that keeps every row in room made beforehand.
struct Keep<S: companion_runtime::domain::record::Task, const N: usize>(Vec<Row<S, N>>);

impl<S: companion_runtime::domain::record::Task, const N: usize>
    companion_runtime::domain::record::RowSink<S, N> for Keep<S, N>
{
    fn log_every(&self) -> u64 {
        1
    }
    fn record(
        &mut self,
        _: u64,
        row: &Row<S, N>,
        _: bool,
    ) -> Result<(), companion_runtime::domain::record::error::RecordError> {
        self.0.push(*row);
        Ok(())
    }
}

/// The in-process loop (`companion sim`'s, and the lockstep plant's) with either arm —
/// measure, step the law, record the row, advance through a pure delay — allocates nothing.
#[test]
fn the_simulation_loop_of_either_arm_allocates_nothing() {
    use companion_runtime::run::sim::{run_loop, InProcess, LoopEnd};
    let silent = companion_runtime::domain::observe::Silent;
    let delayed = |d: f64| {
        Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
            .duration(d)
            .delay(0.0025)
            .build()
            .unwrap()
    };
    // The paper's arm.
    let s = delayed(2.0);
    let mut plant = companion_runtime::run::sim::build_plant(&s).unwrap();
    let mut exchange = InProcess::new(&s).unwrap();
    let mut rows = Keep(Vec::with_capacity(2_100));
    let (n, end) =
        allocations_in(|| run_loop(&s, &mut Robot::of(&mut plant, &s), &mut exchange, &mut rows, &silent));
    assert_eq!((n, end.unwrap(), rows.0.len()), (0, LoopEnd::Completed, 2_001));
    // The UR5.
    use companion_runtime::domain::arm::{ArmChoice, SpatialArmSpec};
    use companion_runtime::run::spatial::{SpatialScenario, SpatialTargetChoice};
    let arm = SpatialArmSpec::from_choice(&ArmChoice::parse("ur5")).unwrap().unwrap();
    let ss =
        SpatialScenario::new(delayed(2.0), arm, SpatialTargetChoice::Lifted(PaperTrajectory::One)).unwrap();
    let star = companion_runtime::run::spatial::target_in_effector::<6>(&ss).unwrap();
    let chain = ss.arm.chain::<f64, 6>().unwrap();
    let mut plant = companion_runtime::run::spatial::build_plant(&ss, &chain, &star).unwrap();
    let law =
        companion_runtime::domain::controller::boxed_spatial_controller::<6>(&ss.base.controller, &ss.arm)
            .unwrap();
    let mut exchange = InProcess::with(law, &ss.base);
    let mut rows = Keep::<companion_core::Spatial, 6>(Vec::with_capacity(2_100));
    let (n, end) = allocations_in(|| {
        let mut robot = Robot { plant: &mut plant, target_in_effector: star };
        run_loop(&ss.base, &mut robot, &mut exchange, &mut rows, &silent)
    });
    assert_eq!((n, end.unwrap(), rows.0.len()), (0, LoopEnd::Completed, 2_001));
    assert!(rows.0[2_000].plant.ep_norm < rows.0[0].plant.ep_norm, "the arm tracks");
}

/// `companion ros2`'s own work in a period allocates nothing: the inputs taken and checked
/// (the HIL's safety rules and the one-writer rule), the generated target, the law's step on the
/// measurement made of them, the command delay's record — 5 000 periods of the UR5 at 1 kHz
/// (more than the delay probe's capacity, so its rings wrap). (The messages' decoding and encoding are RustDDS's
/// and serde's, inside the transport's calls.)
#[cfg(feature = "ros2")]
#[test]
fn the_ros2_nodes_period_allocates_nothing_of_its_own() {
    use companion_core::nalgebra::SVector;
    use companion_core::{Measurement, Pose};
    use companion_runtime::domain::controller::boxed_spatial_controller;
    use companion_runtime::run::ros2::inputs::{Ages, FaultCounts, Latest};
    use companion_runtime::run::ros2::target::{planar_pose, Generator};
    use companion_runtime::transport::ros2::msgs::{self, JointSample, Time};
    use companion_runtime::transport::ros2::{Arrived, Inputs, StampedPose, WriterId};

    let ss = ur5_scenario(5.0);
    let chain = ss.arm.chain::<f64, 6>().unwrap();
    let mut law = boxed_spatial_controller::<6>(&ss.base.controller, &ss.arm).unwrap();
    let star = law.target_in_effector();
    let plant = companion_runtime::run::spatial::build_plant(&ss, &chain, &star).unwrap();
    let mut target = Generator::new(plant, 1e-3);
    let mut latest = Latest::new(6, false);
    let mut counts = FaultCounts::default();
    let ages = Ages { max_age_ns: 5_000_000, silence_ns: 20_000_000 };
    let home = chain.home();
    let base0 = Pose::new(0.5, -0.2, 0.3);
    let robot = WriterId([7; 16]);
    let mut probe = companion_runtime::run::ros2::delay::DelayProbe::<6>::new();
    let (n, finite) = allocations_in(|| {
        let mut finite = true;
        for k in 0..5000u64 {
            let stamp = Time::from_ns(k as i64 * 1_000_000);
            let mut joints = [f64::NAN; 8];
            joints[..6].copy_from_slice(home.as_slice());
            let sample = JointSample { stamp, joints, found: 0b11_1111, malformed: false };
            let inputs = Inputs {
                joints: Arrived::one(robot, sample),
                base: Arrived::one(robot, StampedPose { stamp, pose: msgs::Pose::default() }),
                ..Inputs::default()
            };
            latest.update(&inputs, k * 1_000_000, [1, 1, 0, 0], ages.silence_ns, &mut counts);
            let s = latest.check(k * 1_000_000, k as i64 * 1_000_000 + 200_000, ages).unwrap();
            let t = k as f64 * 1e-3;
            let (pose, twist) = target.at(t, &base0).unwrap();
            let meas = Measurement {
                t,
                base: planar_pose(&s.base).unwrap(),
                steering: 0.0,
                joints: SVector::<f64, 6>::from_column_slice(&s.joints[..6]),
                target: pose,
                target_velocity: twist,
            };
            let r = law.step(&meas, 1e-3, 2e-4);
            probe.joints(s.joints_stamp.as_ns(), &s.joints[..6]);
            let mut sent = [0.0; 6];
            sent.copy_from_slice(r.command.joints.as_slice());
            probe.command(k as i64 * 1_000_000, &sent);
            finite &= r.command.joints.iter().all(|x| x.is_finite()) && r.command.platform.v.is_finite();
        }
        finite
    });
    assert!(finite);
    assert_eq!(n, 0, "the node's period allocated {n} times in 5000 periods");
}
