//! The controller core on an emulated Cortex-M4F (QEMU `mps2-an386`).
//!
//! Runs every case of [`scenario::CASES`] closed loop, prints the scenario's digest lines
//! (compared bit for bit with the host by `tests/tests/firmware_host.rs`) and, per case,
//! the cost of one controller step in instructions, counted by SysTick.
//!
//! How SysTick counts instructions: under QEMU's `-icount shift=s` every instruction
//! advances virtual time by exactly 2^s ns, and SysTick (core clock) ticks at the board's
//! 25 MHz of virtual time, one tick per 40 ns. `tests/firmware/measure` (and the host
//! test) use `shift=7`: 3.2 ticks per instruction, so rounding ticks to instructions is
//! exact for any count. The rate is not assumed: [`calibrate`] times a hand-written loop
//! ([`spin`]) whose instruction count is known by construction and checks that the ticks
//! grow in proportion to it; an empty pair of readings must convert to the same count
//! every time (which fails when ticks are too coarse); the calibration is taken again after
//! the last case and must not have changed. Any failed check ends the run with exit code 3
//! and an `E` line — as does a run without `-icount`, where SysTick follows the host's
//! clock. `measure` then checks the rate against 2^s / 40 ticks per instruction and counts
//! the `S` steps a second way, by single-stepping the same ELF through QEMU's gdb stub
//! (`tests/firmware/gdbcount.py`). Lines it adds:
//!
//! ```text
//! M <flash bytes> <static RAM bytes> <SysTick ticks per 20 000 instructions>
//! K <function> <f32|libm-f32|f64> <mean instructions per call>
//! Q <f32 bit patterns checked> <square roots that differ from libm's sqrtf>
//! S <case> <step index> <instructions of that step>   (the SAMPLE_STEPS, the largest, the largest after the first)
//! C <case> <steps> <sum of instructions> <min> <max> <step of max> <max of the steps after the first> <its step>
//!   <first step> <stack bytes of two steps> <stack bytes of the case> <stack bytes of building the controller and two steps>
//!   <most stack bytes of one step, painted around each> <its step> <bytes painted> <1 if a step reached the paint's end>
//! V <SysTick ticks per 20 000 instructions, measured again after the last case>
//! E <why the counts cannot be trusted>
//! ```
//!
//! The count of a step is the instructions executed between the two SysTick readings
//! around the call of [`scenario::controller_step`] (or [`scenario::spatial_step`]: argument set-up, call, step, return)
//! less those between the readings of an empty pair (the probe's own). The steps' stack is
//! that of the first two steps of a controller already built (the first initialises the
//! state), called from a closure that holds their result; the build's, of building the
//! controller and the same two steps; the case's adds the plant, the digest and the
//! formatting of the output. The stack of one step is measured around every step of the
//! case: a window below the caller's stack pointer is painted before the first SysTick
//! reading and scanned after the second; the most any step wrote, below the caller's
//! stack pointer (the call's own frame and everything under it, not the caller's result).
//!
//! Exit code 0 when every case ran without a rejected step, 1 when a step was rejected,
//! 3 when the SysTick calibration failed its checks, 4 when the FPU's square root
//! (`Real for f32`, `companion-fpu`) differs from libm's `sqrtf` (which the host uses), 101
//! on a panic.
#![no_std]
#![no_main]

mod scenario;

use core::fmt::Write;

use companion_core::Real;
use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::entry;

use scenario::{NoStack, Probe, StackProbe, CASES};

/// Line-buffered semihosting stdout (one host call per line, not per fragment).
struct Out {
    buf: [u8; 256],
    len: usize,
}

impl Out {
    const fn new() -> Self {
        Self { buf: [0; 256], len: 0 }
    }

    fn flush(&mut self) {
        if self.len > 0 {
            if let Ok(mut out) = semihosting::io::stdout() {
                let _ = semihosting::io::Write::write_all(&mut out, &self.buf[..self.len]);
            }
            self.len = 0;
        }
    }
}

impl Write for Out {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            if self.len == self.buf.len() {
                self.flush();
            }
            self.buf[self.len] = b;
            self.len += 1;
            if b == b'\n' {
                self.flush();
            }
        }
        Ok(())
    }
}

const SYST_MASK: u32 = 0x00ff_ffff;

/// SysTick's current value (it counts down from `SYST_MASK` and wraps).
#[inline(always)]
fn ticks() -> u32 {
    SYST::get_current()
}

/// Ticks elapsed between two readings (valid below 2²⁴ ticks).
#[inline(always)]
fn elapsed(start: u32, end: u32) -> u32 {
    start.wrapping_sub(end) & SYST_MASK
}

/// Converts SysTick ticks to instructions.
#[derive(Clone, Copy, Debug)]
struct Clock {
    /// SysTick ticks per [`CALIBRATION_INSTRUCTIONS`] instructions (from [`calibrate`]).
    per: u32,
    /// Instructions of an empty pair of readings (from [`empty_bracket`]), subtracted
    /// from every count: a count is then the instructions strictly between the readings.
    overhead: u32,
}

impl Clock {
    /// Instructions in `t` ticks, rounded to the nearest. Exact while a tick is less than
    /// a third of an instruction (`-icount shift=7`: 3.2 ticks per instruction, so one
    /// tick of quantisation at each end is 0.31 instruction).
    fn instructions(self, t: u32) -> u32 {
        let n = (u64::from(t) * u64::from(CALIBRATION_INSTRUCTIONS) + u64::from(self.per) / 2)
            / u64::from(self.per.max(1));
        u32::try_from(n).unwrap_or(u32::MAX)
    }
}

/// Counts instructions per controller step: sum (for the mean), min, max and where, the
/// largest after the first step and where, the first step, and the steps of
/// [`SAMPLE_STEPS`]; and, when `window > 0`, the stack of each step by painting.
struct Meter {
    start: u32,
    clock: Clock,
    n: u32,
    sum: u64,
    min: u32,
    max: u32,
    /// The step of `max` (the first of equal ones).
    max_at: u32,
    /// The largest count of the steps after the first (which initialises the state).
    max_later: u32,
    /// The step of `max_later`.
    max_later_at: u32,
    first: u32,
    samples: [u32; SAMPLE_STEPS.len()],
    /// Bytes below the stack pointer painted before each step (0: no painting).
    window: usize,
    /// The stack pointer at the step's call (the top of the painted window).
    top: usize,
    /// The most stack one step used (bytes below the caller's stack pointer).
    stack: usize,
    /// The step of `stack`.
    stack_at: u32,
    /// Whether a step wrote the lowest word of the window (then `stack` is a lower bound).
    overflow: bool,
}

impl Meter {
    fn new(clock: Clock, window: usize) -> Self {
        Self {
            start: 0,
            clock,
            n: 0,
            sum: 0,
            min: u32::MAX,
            max: 0,
            max_at: 0,
            max_later: 0,
            max_later_at: 0,
            first: 0,
            samples: [0; SAMPLE_STEPS.len()],
            window,
            top: 0,
            stack: 0,
            stack_at: 0,
            overflow: false,
        }
    }

    /// The mean count, rounded to the nearest.
    fn mean(&self) -> u64 {
        let n = u64::from(self.n.max(1));
        (self.sum + n / 2) / n
    }
}

impl Probe for Meter {
    #[inline(always)]
    fn enter(&mut self) {
        if self.n == COMPANION_STOP_AT.load(core::sync::atomic::Ordering::Relaxed) {
            companion_step_mark(self.n);
        }
        if self.window > 0 {
            // Paint [sp − window, sp): the step's frames will be there, and nothing
            // else writes below the stack pointer of this (the caller's) frame until the
            // step is called.
            let top = stack_pointer_register() & !3;
            let bottom = top.saturating_sub(self.window).max(stack_floor());
            self.top = top;
            let mut p = bottom;
            while p < top {
                // SAFETY: [bottom, top) is RAM below the stack pointer (free: the step
                // is not yet called and this loop keeps its state in registers) and
                // above every static (`.bss` ends at the floor).
                unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
                p += 4;
            }
        }
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        self.start = ticks();
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
    }

    #[inline(always)]
    fn leave(&mut self) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        let end = ticks();
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        let d = self.clock.instructions(elapsed(self.start, end)).saturating_sub(self.clock.overhead);
        if self.n == 0 {
            self.first = d;
        } else if d > self.max_later {
            self.max_later = d;
            self.max_later_at = self.n;
        }
        if let Some(i) = SAMPLE_STEPS.iter().position(|&k| k == self.n) {
            self.samples[i] = d;
        }
        if d > self.max || self.n == 0 {
            self.max = d;
            self.max_at = self.n;
        }
        if self.window > 0 {
            let bottom = self.top.saturating_sub(self.window).max(stack_floor());
            let mut p = bottom;
            // SAFETY: reads the painted window, RAM below this frame's stack pointer.
            while p < self.top && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
                p += 4;
            }
            let used = self.top - p;
            if used > self.stack {
                self.stack = used;
                self.stack_at = self.n;
            }
            self.overflow |= p == bottom;
        }
        self.n += 1;
        self.sum += u64::from(d);
        self.min = self.min.min(d);
    }
}

/// The stack pointer (the register, not the address of a local, which is above it).
#[inline(always)]
fn stack_pointer_register() -> usize {
    let sp: usize;
    // SAFETY: copies SP into a register; no memory access, flags unchanged.
    unsafe { core::arch::asm!("mov {}, sp", out(reg) sp, options(nomem, nostack, preserves_flags)) };
    sp
}

/// The step of the current case before which [`companion_step_mark`] is called (none
/// unless `gdbcount.py` writes one here, through QEMU's gdb stub).
#[no_mangle]
static COMPANION_STOP_AT: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(u32::MAX);

/// Called before step [`COMPANION_STOP_AT`] of a case, outside the step's SysTick
/// readings (the next reading starts the step): `gdbcount.py` breaks here instead of at
/// each of the steps before. Exported and never inlined, as [`companion_case_start`].
#[no_mangle]
#[inline(never)]
pub extern "C" fn companion_step_mark(step: u32) {
    black_box(step);
}

/// Marks the start of a case (called just before it, with its name): `gdbcount.py` breaks
/// here, reads the name (pointer in r0, length in r1) and numbers the calls of the case's
/// step function from here. Exported unmangled so that its name and calling convention are
/// fixed; never inlined.
#[no_mangle]
#[inline(never)]
pub extern "C" fn companion_case_start(name: *const u8, len: usize) {
    black_box((name, len));
}

/// Instructions of an empty `enter`/`leave` pair, least and most of 16 (equal when the
/// counts are exact).
#[inline(never)]
fn empty_bracket(per: u32) -> (u32, u32) {
    let mut m = Meter::new(Clock { per, overhead: 0 }, 0);
    for _ in 0..16 {
        m.enter();
        m.leave();
    }
    (m.min, m.max)
}

/// Runs `n` iterations (`n ≥ 1`) of a hand-written two-instruction loop (`subs; bne`):
/// `spin(a + k)` executes exactly `2 k` more instructions than `spin(a)`, whatever the
/// compiler does around the loop.
#[inline(never)]
fn spin(n: u32) {
    // SAFETY: arithmetic on one register and a branch back within the asm block; no
    // memory, no stack.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, #1",
            "bne 2b",
            n = inout(reg) n.max(1) => _,
            options(nomem, nostack),
        );
    }
}

/// Iterations of [`spin`] in each calibration interval.
const CALIBRATION_ITERATIONS: u32 = 10_000;

/// Instructions in each calibration interval: two per iteration of [`spin`].
const CALIBRATION_INSTRUCTIONS: u32 = 2 * CALIBRATION_ITERATIONS;

/// SysTick ticks of `spin(n)`.
#[inline(never)]
fn spin_ticks(n: u32) -> u32 {
    let start = ticks();
    spin(n);
    elapsed(start, ticks())
}

/// SysTick ticks per [`CALIBRATION_INSTRUCTIONS`] instructions, measured twice: as
/// `spin(a + k) − spin(a)` and as `spin(a + 2k) − spin(a + k)`. Under `-icount` the two
/// agree to a tick (ticks are counted from the instructions); when they do not, ticks
/// are not proportional to instructions and no count is worth printing.
#[inline(never)]
fn calibrate() -> (u32, u32) {
    const BASE: u32 = 1_000;
    let base = spin_ticks(BASE);
    let one = spin_ticks(BASE + CALIBRATION_ITERATIONS);
    let two = spin_ticks(BASE + 2 * CALIBRATION_ITERATIONS);
    (one.saturating_sub(base), two.saturating_sub(one))
}

/// Whether two calibrations agree to one tick.
fn agree(a: u32, b: u32) -> bool {
    a.abs_diff(b) <= 1
}

/// Steps whose counts are printed one by one (`S` lines): `measure` counts the same steps
/// by single-stepping (`gdbcount.py`, which can bracket any step but the first) and
/// compares.
const SAMPLE_STEPS: [u32; 3] = [1, 2, 100];

// Symbols of cortex-m-rt's link.x.
extern "C" {
    static __sidata: u32;
    static __sdata: u32;
    static __edata: u32;
    static __ebss: u32;
}

const RAM_START: usize = 0x2000_0000;
const PAINT: u32 = 0x5afe_c0de;

/// The address just below the current stack frame.
#[inline(always)]
fn stack_pointer() -> usize {
    let here = 0u32;
    core::ptr::addr_of!(here) as usize
}

/// The lowest RAM address that stacks may reach: the end of `.bss`.
fn stack_floor() -> usize {
    (core::ptr::addr_of!(__ebss) as usize + 7) & !7
}

/// Fills the free stack below this function's own frame (less a margin) with the pattern.
#[inline(never)]
fn paint() {
    let end = stack_pointer() - 64;
    let mut p = stack_floor();
    while p + 4 <= end {
        // SAFETY: [floor, end) is RAM below every live stack frame (this function calls
        // nothing and its frame is above `end`) and above every static (`.bss` ends at
        // the floor).
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// The lowest address whose pattern was overwritten since [`paint`] (`top` if none).
#[inline(never)]
fn low_water(top: usize) -> usize {
    let mut p = stack_floor();
    while p + 4 <= top {
        // SAFETY: reads RAM between the end of `.bss` and a live stack frame.
        if unsafe { core::ptr::read_volatile(p as *const u32) } != PAINT {
            return p;
        }
        p += 4;
    }
    top
}

/// Bytes of stack `f` uses below the caller's frame.
#[inline(never)]
fn stack_of(f: impl FnOnce()) -> usize {
    let top = stack_pointer();
    paint();
    f();
    top.saturating_sub(low_water(top))
}

/// The firmware's [`StackProbe`]: [`stack_of`].
struct Painter;

impl StackProbe for Painter {
    fn measure(&mut self, f: &mut dyn FnMut()) -> usize {
        stack_of(f)
    }
}

/// Arguments typical of the law: angles within ±2π (`e^x` is called with −|x|).
const FUNCTION_ARGS: [f64; 8] = [0.3, 1.2, -2.5, 3.0, 0.05, 2.0, -0.7, 5.5];

/// Prints the mean instructions of one call of `f` (including a call through `dyn`).
fn function_cost<T: Real>(out: &mut Out, name: &str, ty: &str, clock: Clock, f: &dyn Fn(T) -> T) {
    let mut m = Meter::new(clock, 0);
    for a in FUNCTION_ARGS {
        // The argument is converted before the first reading (black_box) and passes
        // through black_box after it, so the call can be neither hoisted above the first
        // reading nor sunk below the second.
        let x = black_box(T::of(a));
        m.enter();
        let y = f(black_box(x));
        black_box(y);
        m.leave();
    }
    let _ = writeln!(out, "K {name} {ty} {}", m.mean());
}

/// Each elementary function of [`Real`] for `T`.
fn function_costs<T: Real>(out: &mut Out, ty: &str, clock: Clock) {
    function_cost::<T>(out, "sincos", ty, clock, &|x| {
        let (s, c) = x.sincos();
        s + c
    });
    function_cost::<T>(out, "atan", ty, clock, &|x| x.arctan());
    function_cost::<T>(out, "atan2", ty, clock, &|x| x.arctan2(T::of(-1.3)));
    function_cost::<T>(out, "exp", ty, clock, &|x| (-x.abs()).exponential());
    function_cost::<T>(out, "sqrt", ty, clock, &|x| x.abs().square_root());
    function_cost::<T>(out, "round", ty, clock, &|x| (x * T::of(3.3)).round_nearest());
}

/// The law's `f32` square root (the FPU's `vsqrt.f32` here) against libm's `sqrtf` (the
/// host's) on every 4 093rd bit pattern of `f32`, both signs, and the special values: the
/// patterns checked and how many roots differ (NaN results count as equal).
fn sqrt_sweep() -> (u32, u32) {
    let (mut checked, mut differ) = (0u32, 0u32);
    let mut check = |x: f32| {
        let (a, b) = (black_box(x).square_root(), libm::sqrtf(black_box(x)));
        checked += 1;
        if a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()) {
            differ += 1;
        }
    };
    let mut bits = 0u64;
    while bits <= u64::from(u32::MAX) {
        check(f32::from_bits(bits as u32));
        bits += 4093;
    }
    for x in [0.0, -0.0, f32::MIN_POSITIVE, f32::MAX, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1.0, 4.0] {
        check(x);
    }
    (checked, differ)
}

/// libm's `f32` functions, which `Real for f32` used before `fastmath` (for comparison).
fn libm_f32_costs(out: &mut Out, clock: Clock) {
    let ty = "libm-f32";
    function_cost::<f32>(out, "sincos", ty, clock, &|x| {
        let (s, c) = libm::sincosf(x);
        s + c
    });
    function_cost::<f32>(out, "atan", ty, clock, &libm::atanf);
    function_cost::<f32>(out, "atan2", ty, clock, &|x| libm::atan2f(x, -1.3));
    function_cost::<f32>(out, "exp", ty, clock, &|x| libm::expf(-x.abs()));
    function_cost::<f32>(out, "sqrt", ty, clock, &|x| libm::sqrtf(x.abs()));
    function_cost::<f32>(out, "round", ty, clock, &|x| libm::roundf(x * 3.3));
}

#[entry]
fn main() -> ! {
    let mut out = Out::new();
    let Some(mut cp) = cortex_m::Peripherals::take() else { semihosting::process::exit(2) };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(SYST_MASK);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();

    let flash = core::ptr::addr_of!(__sidata) as usize
        + (core::ptr::addr_of!(__edata) as usize - core::ptr::addr_of!(__sdata) as usize);
    let ram = core::ptr::addr_of!(__ebss) as usize - RAM_START;
    let (per, again) = calibrate();
    let _ = writeln!(out, "M {flash} {ram} {per}");
    if per == 0 || !agree(per, again) {
        fail(
            &mut out,
            format_args!(
                "calibration: {per} then {again} SysTick ticks for the same {CALIBRATION_INSTRUCTIONS} \
                 instructions; ticks do not count instructions (run under QEMU -icount)"
            ),
        );
    }
    let (overhead, most) = empty_bracket(per);
    if overhead != most {
        fail(
            &mut out,
            format_args!(
                "an empty pair of readings took {overhead} to {most} instructions: \
                 {per} ticks per {CALIBRATION_INSTRUCTIONS} instructions are too few to count exactly \
                 (use -icount shift=7 or more)"
            ),
        );
    }
    let clock = Clock { per, overhead };
    let (checked, differ) = sqrt_sweep();
    let _ = writeln!(out, "Q {checked} {differ}");
    if differ > 0 {
        let _ = writeln!(
            out,
            "E the FPU's square root differs from libm's sqrtf for {differ} of {checked} inputs"
        );
        semihosting::process::exit(4)
    }
    function_costs::<f32>(&mut out, "f32", clock);
    libm_f32_costs(&mut out, clock);
    function_costs::<f64>(&mut out, "f64", clock);
    let mut failed = false;
    for case in &CASES {
        // The steps alone (the controller built before the stack is painted), then
        // building the controller and the same steps.
        let step_stack = scenario::first_steps(case, &mut Painter);
        let build_stack = stack_of(|| {
            scenario::first_steps(case, &mut NoStack);
        });
        // Each step's stack painted in a window of twice the first two steps' and 1 KiB.
        let mut meter = Meter::new(clock, (2 * step_stack + 1024 + 3) & !3);
        let mut outcome = None;
        companion_case_start(case.name.as_ptr(), case.name.len());
        let case_stack = stack_of(|| outcome = Some(scenario::run_case(case, &mut out, &mut meter)));
        if outcome.is_none_or(|o| o.rejected > 0) {
            failed = true;
        }
        for (k, n) in SAMPLE_STEPS.iter().zip(meter.samples) {
            let _ = writeln!(out, "S {} {k} {n}", case.name);
        }
        let _ = writeln!(out, "S {} {} {}", case.name, meter.max_at, meter.max);
        let _ = writeln!(out, "S {} {} {}", case.name, meter.max_later_at, meter.max_later);
        let _ = writeln!(
            out,
            "C {} {} {} {} {} {} {} {} {} {step_stack} {case_stack} {build_stack} {} {} {} {}",
            case.name,
            meter.n,
            meter.sum,
            meter.min,
            meter.max,
            meter.max_at,
            meter.max_later,
            meter.max_later_at,
            meter.first,
            meter.stack,
            meter.stack_at,
            meter.window,
            u8::from(meter.overflow),
        );
    }
    let (end, _) = calibrate();
    let _ = writeln!(out, "V {end}");
    if !agree(per, end) {
        fail(
            &mut out,
            format_args!(
                "calibration: {per} SysTick ticks per {CALIBRATION_INSTRUCTIONS} instructions at the start, \
                 {end} at the end; the counts above are not exact"
            ),
        );
    }
    semihosting::process::exit(i32::from(failed))
}

/// Prints an `E` line and exits with 3: the counts cannot be trusted.
fn fail(out: &mut Out, why: core::fmt::Arguments<'_>) -> ! {
    let _ = writeln!(out, "E {why}");
    semihosting::process::exit(3)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let mut out = Out::new();
    let _ = writeln!(out, "PANIC {info}");
    semihosting::process::exit(101)
}
