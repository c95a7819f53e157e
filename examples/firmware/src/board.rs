//! Clocks and the 1 kHz timer, per board.
//!
//! * `nucleo` (default): Nucleo-F446RE. HSI 16 MHz → PLL (M 8, N 168, P 2) → SYSCLK 168 MHz,
//!   AHB 168 MHz, APB1 42 MHz (TIM2 runs at twice that, 84 MHz), APB2 84 MHz, flash 5 wait
//!   states. Untested on hardware here.
//! * `qemu`: QEMU's `netduinoplus2` (STM32F405). QEMU does not emulate the RCC (it reads 0,
//!   so waiting for `PLLRDY` would never end): no clock set-up; QEMU clocks TIM2–TIM5 at a
//!   fixed 1 GHz of virtual time (measured: 16 000 040 counts over 2 000 002 instructions
//!   at 8 ns each under `-icount shift=3`).

use stm32f4::stm32f446 as pac;

/// The control period (s) and the timer's rate (Hz).
pub const PERIOD_HZ: u32 = 1000;

/// TIM2's input clock (Hz): QEMU's fixed rate for the STM32F4 timers.
#[cfg(feature = "qemu")]
pub const TIM2_CLOCK_HZ: u32 = 1_000_000_000;
/// TIM2's input clock (Hz): APB1 42 MHz, doubled because APB1's prescaler is not 1.
#[cfg(not(feature = "qemu"))]
pub const TIM2_CLOCK_HZ: u32 = 84_000_000;

/// Nucleo: TIM2 counts at 1 MHz (PSC 83) and overflows every 1 000 counts (ARR 999).
#[cfg(not(feature = "qemu"))]
const PSC: u16 = {
    let p = TIM2_CLOCK_HZ / 1_000_000 - 1;
    assert!(p <= u16::MAX as u32 && TIM2_CLOCK_HZ % 1_000_000 == 0);
    p as u16
};
#[cfg(not(feature = "qemu"))]
const ARR: u32 = 1_000_000 / PERIOD_HZ - 1;
/// Nanoseconds per TIM2 count.
#[cfg(not(feature = "qemu"))]
pub const COUNT_NS: u32 = 1_000;

/// QEMU: TIM2 counts at 1 GHz (PSC 0). QEMU 7.2's timer model fires its update interrupt
/// every `(ARR + offset) × (PSC + 1)` input clocks, not `ARR + 1`, where `offset` is reset to
/// the current count by writes to CNT, EGR or a non-zero PSC; and its CNT never wraps at
/// ARR. With PSC 0, no EGR write and no CNT write the offset stays 0, so ARR = 1 000 000
/// gives exactly 1 ms of virtual time (on a real STM32 that would be 1 000 001 counts).
#[cfg(feature = "qemu")]
const PSC: u16 = 0;
#[cfg(feature = "qemu")]
const ARR: u32 = TIM2_CLOCK_HZ / PERIOD_HZ;
/// Nanoseconds per TIM2 count.
#[cfg(feature = "qemu")]
pub const COUNT_NS: u32 = 1;

/// Sets up the clock tree (nothing under QEMU).
#[cfg(feature = "qemu")]
pub fn clocks(_rcc: &pac::RCC, _flash: &pac::FLASH) {}

/// Sets up the clock tree: 168 MHz from the HSI through the PLL.
#[cfg(not(feature = "qemu"))]
pub fn clocks(rcc: &pac::RCC, flash: &pac::FLASH) {
    // Flash wait states first (5 WS for 150–168 MHz at 2.7–3.6 V), prefetch and caches on.
    flash.acr().modify(|_, w| w.latency().ws5().prften().set_bit().icen().set_bit().dcen().set_bit());
    while !flash.acr().read().latency().is_ws5() {}
    // SAFETY: PLLM = 8 (HSI/8 = 2 MHz VCO input) and PLLN = 168 (336 MHz VCO) are inside
    // the ranges of RM0390 §6.3.2 (2..=63 and 50..=432); PLLQ 7 gives 48 MHz, PLLR 2.
    rcc.pllcfgr().write(|w| unsafe {
        w.pllsrc().hsi().pllm().bits(8).plln().bits(168).pllp().div2().pllq().bits(7).pllr().bits(2)
    });
    rcc.cfgr().modify(|_, w| w.hpre().div1().ppre1().div4().ppre2().div2());
    rcc.cr().modify(|_, w| w.pllon().set_bit());
    while rcc.cr().read().pllrdy().bit_is_clear() {}
    rcc.cfgr().modify(|_, w| w.sw().pll());
    while !rcc.cfgr().read().sws().is_pll() {}
}

/// Real STM32, for a debugger (probe-rs): TIM2 stops while the debugger halts the core (as
/// every semihosting call does), so that a halt does not swallow periods, and the debug
/// port stays clocked in `idle`'s `wfi`. Not under QEMU, which has no DBGMCU.
#[cfg(not(feature = "qemu"))]
pub fn freeze_tim2_in_debug(dbgmcu: &pac::DBGMCU) {
    dbgmcu.apb1_fz().modify(|_, w| w.dbg_tim2_stop().set_bit());
    dbgmcu.cr().modify(|_, w| w.dbg_sleep().set_bit());
}

/// Nothing to do under QEMU.
#[cfg(feature = "qemu")]
pub fn freeze_tim2_in_debug(_dbgmcu: &pac::DBGMCU) {}

/// Starts TIM2 with its update interrupt every 1 ms (RTIC unmasks the interrupt after
/// `init`).
pub fn start_tim2(rcc: &pac::RCC, tim2: &pac::TIM2) {
    rcc.apb1enr().modify(|_, w| w.tim2en().set_bit());
    tim2.psc().write(|w| w.psc().set(PSC));
    tim2.arr().write(|w| w.arr().set(ARR));
    // Real STM32: load the prescaler now (it is buffered until an update event), then drop
    // the flag that this forced update raised. Not under QEMU (see `PSC`).
    #[cfg(not(feature = "qemu"))]
    {
        tim2.egr().write(|w| w.ug().set_bit());
        tim2.sr().write(|w| w.uif().clear());
    }
    tim2.dier().modify(|_, w| w.uie().set_bit());
    tim2.cr1().modify(|_, w| w.cen().set_bit());
}

/// Acknowledges TIM2's update interrupt.
#[inline(always)]
pub fn ack_tim2(tim2: &pac::TIM2) {
    tim2.sr().write(|w| w.uif().clear());
}

/// TIM2's counter: counts of [`COUNT_NS`] since the last update event (Nucleo); since the
/// start (QEMU, whose CNT does not wrap at ARR).
#[inline(always)]
pub fn tim2_count(tim2: &pac::TIM2) -> u32 {
    tim2.cnt().read().bits()
}

/// Stops TIM2 (the end of the run).
pub fn stop_tim2(tim2: &pac::TIM2) {
    tim2.cr1().modify(|_, w| w.cen().clear_bit());
    tim2.dier().modify(|_, w| w.uie().clear_bit());
    tim2.sr().write(|w| w.uif().clear());
}
