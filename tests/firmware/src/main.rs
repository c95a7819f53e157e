//! The controller core on an emulated Cortex-M4F (QEMU `mps2-an386`).
//!
//! Runs every case of [`scenario::CASES`] closed loop, prints the scenario's digest lines
//! (compared bit for bit with the host by `tests/tests/firmware_host.rs`) and, per case,
//! the cost of one controller step in instructions, counted by SysTick. Under QEMU's
//! `-icount shift=5` one instruction is 32 ns of virtual time, so the counts are exact
//! and deterministic (to ±1 instruction: SysTick ticks every 20 ns of virtual time, and
//! the rate is calibrated against a loop of known length); without `-icount` they are
//! meaningless (QEMU then runs SysTick from the host clock) and only the digests count.
//! Lines it adds:
//!
//! ```text
//! M <flash bytes> <static RAM bytes> <SysTick ticks per 20 000 instructions>
//! K <function> <f32|libm-f32|f64> <mean instructions per call>
//! C <case> <mean instructions/step> <min> <max> <first step> <stack bytes of a step> <stack bytes of the case>
//! ```
//!
//! The step's stack is that of building the controller and two steps; the case's adds
//! the plant, the digest and the formatting of the output.
//!
//! Exit code 0 when every case ran without a rejected step, 1 otherwise, 101 on a panic.
#![no_std]
#![no_main]

mod scenario;

use core::fmt::Write;

use companion_core::Real;
use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::entry;

use scenario::{Probe, CASES};

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

/// Counts SysTick ticks per controller step: mean, min, max, and the first step.
struct Meter {
    start: u32,
    overhead: u32,
    n: u32,
    sum: u64,
    min: u32,
    max: u32,
    first: u32,
}

impl Meter {
    fn new(overhead: u32) -> Self {
        Self { start: 0, overhead, n: 0, sum: 0, min: u32::MAX, max: 0, first: 0 }
    }
}

impl Probe for Meter {
    #[inline(always)]
    fn enter(&mut self) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        self.start = ticks();
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
    }

    #[inline(always)]
    fn leave(&mut self) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        let end = ticks();
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        let d = elapsed(self.start, end).saturating_sub(self.overhead);
        if self.n == 0 {
            self.first = d;
        }
        self.n += 1;
        self.sum += u64::from(d);
        self.min = self.min.min(d);
        self.max = self.max.max(d);
    }
}

/// Ticks of an empty `enter`/`leave` pair (subtracted from every measurement).
#[inline(never)]
fn probe_overhead() -> u32 {
    let mut m = Meter::new(0);
    let mut best = u32::MAX;
    for _ in 0..16 {
        m.enter();
        m.leave();
        best = best.min(m.max);
        m.max = 0;
    }
    best
}

/// Instructions in the difference of the two calibration loops: `delay(n)` runs
/// `1 + n/2` iterations of `subs; bne`, so `delay(2 N + 2 K)` − `delay(2 N)` is `2 K`
/// instructions.
const CALIBRATION_INSTRUCTIONS: u32 = 20_000;

/// SysTick ticks per [`CALIBRATION_INSTRUCTIONS`] instructions. Under `-icount shift=s`
/// an instruction takes 2^s ns of virtual time; SysTick's rate on this board is
/// whatever QEMU gives it (20 ns per tick in QEMU 7.2), so it is measured, not assumed.
#[inline(never)]
fn calibrate() -> u32 {
    let run = |n: u32| {
        let start = ticks();
        cortex_m::asm::delay(n);
        elapsed(start, ticks())
    };
    let short = run(20_000);
    let long = run(20_000 + CALIBRATION_INSTRUCTIONS);
    long.saturating_sub(short)
}

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

/// Arguments typical of the law: angles within ±2π (`e^x` is called with −|x|).
const FUNCTION_ARGS: [f64; 8] = [0.3, 1.2, -2.5, 3.0, 0.05, 2.0, -0.7, 5.5];

/// Prints the mean instructions of one call of `f` (including a call through `dyn`).
fn function_cost<T: Real>(out: &mut Out, name: &str, ty: &str, cost: &Cost<'_>, f: &dyn Fn(T) -> T) {
    let mut m = Meter::new(cost.overhead);
    for a in FUNCTION_ARGS {
        let x = T::of(a);
        m.enter();
        // black_box inside the bracket: the call cannot be hoisted above the first reading.
        let y = f(black_box(x));
        black_box(y);
        m.leave();
    }
    let mean = (cost.to_instructions)(m.sum) / u64::from(m.n.max(1));
    let _ = writeln!(out, "K {name} {ty} {mean}");
}

/// The probe's overhead (ticks) and the tick-to-instruction conversion.
struct Cost<'a> {
    overhead: u32,
    to_instructions: &'a dyn Fn(u64) -> u64,
}

/// Each elementary function of [`Real`] for `T`.
fn function_costs<T: Real>(out: &mut Out, ty: &str, cost: &Cost<'_>) {
    function_cost::<T>(out, "sincos", ty, cost, &|x| {
        let (s, c) = x.sincos();
        s + c
    });
    function_cost::<T>(out, "atan", ty, cost, &|x| x.arctan());
    function_cost::<T>(out, "atan2", ty, cost, &|x| x.arctan2(T::of(-1.3)));
    function_cost::<T>(out, "exp", ty, cost, &|x| (-x.abs()).exponential());
    function_cost::<T>(out, "sqrt", ty, cost, &|x| x.abs().square_root());
    function_cost::<T>(out, "round", ty, cost, &|x| (x * T::of(3.3)).round_nearest());
}

/// libm's `f32` functions, which `Real for f32` used before `fastmath` (for comparison).
fn libm_f32_costs(out: &mut Out, cost: &Cost<'_>) {
    let ty = "libm-f32";
    function_cost::<f32>(out, "sincos", ty, cost, &|x| {
        let (s, c) = libm::sincosf(x);
        s + c
    });
    function_cost::<f32>(out, "atan", ty, cost, &libm::atanf);
    function_cost::<f32>(out, "atan2", ty, cost, &|x| libm::atan2f(x, -1.3));
    function_cost::<f32>(out, "exp", ty, cost, &|x| libm::expf(-x.abs()));
    function_cost::<f32>(out, "sqrt", ty, cost, &|x| libm::sqrtf(x.abs()));
    function_cost::<f32>(out, "round", ty, cost, &|x| libm::roundf(x * 3.3));
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
    let per = calibrate();
    let _ = writeln!(out, "M {flash} {ram} {per}");
    let overhead = probe_overhead();
    // Ticks to instructions, rounded.
    let instructions =
        |t: u64| (t * u64::from(CALIBRATION_INSTRUCTIONS) + u64::from(per) / 2) / u64::from(per.max(1));
    let cost = Cost { overhead, to_instructions: &instructions };
    function_costs::<f32>(&mut out, "f32", &cost);
    libm_f32_costs(&mut out, &cost);
    function_costs::<f64>(&mut out, "f64", &cost);
    let mut failed = false;
    for case in &CASES {
        let step_stack = stack_of(|| scenario::first_step(case));
        let mut meter = Meter::new(overhead);
        let mut outcome = None;
        let case_stack = stack_of(|| outcome = Some(scenario::run_case(case, &mut out, &mut meter)));
        if outcome.is_none_or(|o| o.rejected > 0) {
            failed = true;
        }
        let mean = instructions(meter.sum) / u64::from(meter.n.max(1));
        let (min, max, first) = (
            instructions(meter.min.into()),
            instructions(meter.max.into()),
            instructions(meter.first.into()),
        );
        let _ = writeln!(out, "C {} {mean} {min} {max} {first} {step_stack} {case_stack}", case.name);
    }
    semihosting::process::exit(i32::from(failed))
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let mut out = Out::new();
    let _ = writeln!(out, "PANIC {info}");
    semihosting::process::exit(101)
}
