//! companion-core on an STM32F4 with RTIC 2: the controller stepped from TIM2's 1 kHz update
//! interrupt, its measurement and command through the [`robot::Robot`] trait, a stub plant
//! in a lower-priority task closing the loop, `‖e_p‖` printed every 100 ms by semihosting.
//! The run's first step — the one that costs about three steps — is taken by the start call
//! in `init`, before TIM2's interrupt is enabled ([`start`]): every step inside the
//! interrupt is a steady-state one.
//!
//! | task | kind | priority | does |
//! |---|---|---|---|
//! | `init` | | | the controller, the start call (the first step at `t = 0`), TIM2 on |
//! | `control` | hardware, TIM2 update | 3 | `t = k·1 ms` from the tick count (`k ≥ 1`), `measure`, `step`, `apply` |
//! | `plant` | software (async) | 2 | the stub plant: integrates each command over 1 ms |
//! | `report` | software (async) | 1 | prints `‖e_p‖`, judges the run, exits |
//! | `idle` | — | 0 | `wfi` |
//!
//! Exit code (semihosting) 0 when the loop closed ([`report::Verdict::closed`]), 1 when it
//! did not (or the start call was rejected), 2 when the parameters were refused.
#![no_std]
#![no_main]

mod board;
mod plant;
mod report;
mod robot;
mod stack;

use companion_core::{Controller, Output, Rpr, Unicycle};

use robot::Robot;

/// The controller: `f32`, unicycle, the RPR arm, three joints.
pub type Law = Controller<f32, Unicycle<f32>, Rpr<f32>, { robot::JOINTS }>;

/// Simulated time the run lasts (ms).
pub const DURATION_MS: u32 = 10_000;

/// The control period (s).
pub const DT: f32 = 1e-3;

/// The law's output, kept where the control task writes it in place.
pub type LawOutput = Output<f32, { robot::JOINTS }>;

/// The start call, in `init` before the control interrupt is enabled: the measurement at
/// `t = 0`, the run's first step ([`Controller::start_into`]: its hold predicted in three
/// passes, about three steps' cost), its command out. Returns `‖e_p‖`, `None` when the law
/// rejected the measurement (the safe command was applied).
pub fn start<R: Robot>(law: &mut Law, robot: &mut R, out: &mut LawOutput) -> Option<f32> {
    let meas = robot.measure(0.0);
    let accepted = law.start_into(&meas, DT, 0.0, out).is_ok();
    // On a rejection `out.command` is the safe command.
    robot.apply(&out.command);
    accepted.then(|| out.diagnostics.e_p.norm())
}

/// One control period, the part of the control task that is the same on any board: the
/// time of period `k` from the integer count (`t = k × 1 ms`, exact while `k < 2²⁴`, i.e.
/// for 4.6 h; no sum of periods, so no drift), the measurement, one step of the law written
/// into `out` in place, the command out — the safe command (all zero) when the law rejects
/// the step. Returns `‖e_p‖`, `None` for a rejected step.
pub fn period<R: Robot>(law: &mut Law, robot: &mut R, k: u32, out: &mut LawOutput) -> Option<f32> {
    let t = k as f32 * DT;
    let meas = robot.measure(t);
    let accepted = law.step_into(&meas, DT, out).is_ok();
    robot.apply(&out.command);
    accepted.then(|| out.diagnostics.e_p.norm())
}

/// Ends the run with this exit code (semihosting; under a debugger, its exit request).
fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    use core::fmt::Write;
    let _ = writeln!(report::Out::new(), "panic: {info}");
    exit(101)
}

#[rtic::app(device = stm32f4::stm32f446, peripherals = true, dispatchers = [UART4, UART5])]
mod app {
    use core::fmt::Write;

    use rtic_sync::channel::{Receiver, Sender};
    use rtic_sync::make_channel;

    use crate::plant::PlantState;
    use crate::report::{seconds, Out, Report, Tally, Verdict, EVERY};
    use crate::robot::{Cmd, StubRobot, DEPTH, JOINTS};
    use crate::{board, exit, stack, Law, LawOutput, DT, DURATION_MS};
    use companion_core::{Controller, Output, PaperRun, Params, Rpr, Unicycle};
    use stm32f4::stm32f446 as pac;

    /// Samples in flight to the report task.
    const REPORTS: usize = 4;

    #[shared]
    struct Shared {}

    #[local]
    struct Local {
        tim2: pac::TIM2,
        law: Law,
        /// The law's output, written in place by each step.
        output: LawOutput,
        /// The robot the control task drives. Your drivers: a type of yours implementing
        /// [`crate::robot::Robot`] here and in `init`, and the `plant` task deleted.
        robot: StubRobot,
        reports: Sender<'static, Report, REPORTS>,
        plant: PlantState,
        plant_commands: Receiver<'static, Cmd, DEPTH>,
        plant_states: Sender<'static, PlantState, DEPTH>,
        report_inbox: Receiver<'static, Report, REPORTS>,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        stack::paint();
        let dp = cx.device;
        board::clocks(&dp.RCC, &dp.FLASH);

        let Ok(mut law) =
            Controller::new(Params::<f32, JOINTS>::paper(PaperRun::A), Unicycle::paper(), Rpr::paper())
        else {
            let _ = writeln!(Out::new(), "E the paper's parameters were refused");
            exit(2)
        };
        let (command_tx, command_rx) = make_channel!(Cmd, DEPTH);
        let (mut state_tx, state_rx) = make_channel!(PlantState, DEPTH);
        let (mut report_tx, report_rx) = make_channel!(Report, REPORTS);
        let initial = PlantState::PAPER;
        // The state the start call measures.
        let _ = state_tx.try_send(initial);
        let mut robot = StubRobot::new(command_tx, state_rx, initial);
        // The first step now, before TIM2's interrupt is enabled: the control task then runs
        // steady-state steps only. Its command goes to the plant, which integrates it over
        // the first period once `init` returns.
        let mut output = Output::zero();
        let Some(e_p) = crate::start(&mut law, &mut robot, &mut output) else {
            let _ = writeln!(Out::new(), "E the start call was rejected: the robot does not start");
            exit(1)
        };
        let _ = report_tx.try_send(Report::Sample { k: 0, e_p });

        let _ = writeln!(
            Out::new(),
            "companion RTIC example: unicycle, paper run (a), trajectory 1, f32, 1 kHz on TIM2 ({} Hz input), {} s",
            board::TIM2_CLOCK_HZ,
            seconds(DURATION_MS)
        );
        // Both tasks wait on their channels; they cannot be running yet.
        let _ = plant::spawn();
        let _ = report::spawn();
        board::freeze_tim2_in_debug(&dp.DBGMCU);
        board::start_tim2(&dp.RCC, &dp.TIM2);

        (
            Shared {},
            Local {
                tim2: dp.TIM2,
                law,
                output,
                robot,
                reports: report_tx,
                plant: initial,
                plant_commands: command_rx,
                plant_states: state_tx,
                report_inbox: report_rx,
            },
        )
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The control period: `t` from the integer tick count (no accumulated rounding), the
    /// measurement, one step, the command (the safe command when the step is rejected).
    /// Period 0 was the start call in `init`: the first interrupt is period 1.
    #[task(binds = TIM2, priority = 3, local = [tim2, law, output, robot, reports, k: u32 = 1, last_entry: u32 = 0, tally: Tally = Tally::ZERO])]
    fn control(cx: control::Context) {
        let local = cx.local;
        let entry = board::tim2_count(local.tim2);
        board::ack_tim2(local.tim2);
        let k = *local.k;
        #[cfg(feature = "qemu")]
        if k > 1 {
            // QEMU's CNT runs on from the start: the time since the previous period's entry.
            let period = entry.wrapping_sub(*local.last_entry) * board::COUNT_NS;
            local.tally.period_ns =
                (local.tally.period_ns.0.min(period), local.tally.period_ns.1.max(period));
        }
        *local.last_entry = entry;
        if k > DURATION_MS {
            return; // the run is over; the report task is exiting
        }
        let e_p = crate::period(local.law, local.robot, k, local.output).unwrap_or_else(|| {
            local.tally.rejected += 1;
            f32::NAN
        });
        local.tally.steps += 1;
        if k % EVERY == 0 && local.reports.try_send(Report::Sample { k, e_p }).is_err() {
            local.tally.lost += 1;
        }
        // The task's time from its first instruction to here (TIM2 counts).
        let busy = board::tim2_count(local.tim2).wrapping_sub(entry) * board::COUNT_NS;
        local.tally.busy_max_ns = local.tally.busy_max_ns.max(busy);
        if k == DURATION_MS {
            board::stop_tim2(local.tim2);
            local.tally.stale = local.robot.stale;
            local.tally.dropped = local.robot.dropped;
            if local.reports.try_send(Report::End(*local.tally)).is_err() {
                let _ = writeln!(Out::new(), "E the final report was lost");
                exit(1);
            }
        }
        *local.k = k + 1;
    }

    /// The stub plant: each command held for one period, then the new state back.
    #[task(priority = 2, local = [plant, plant_commands, plant_states])]
    async fn plant(cx: plant::Context) {
        let local = cx.local;
        while let Ok(cmd) = local.plant_commands.recv().await {
            local.plant.advance(&cmd, DT);
            let _ = local.plant_states.try_send(*local.plant);
        }
    }

    /// Prints `‖e_p‖` every 100 ms, judges the run at its end and exits.
    #[task(priority = 1, local = [report_inbox])]
    async fn report(cx: report::Context) {
        let mut verdict = Verdict::new();
        let mut out = Out::new();
        while let Ok(r) = cx.local.report_inbox.recv().await {
            match r {
                Report::Sample { k, e_p } => {
                    verdict.sample(k, e_p);
                    let _ = writeln!(out, "t = {} s  |e_p| = {:.6e} m", seconds(k), e_p);
                }
                Report::End(tally) => {
                    let (first, last, rises) = verdict.figures();
                    let closed = verdict.closed(&tally);
                    let _ = writeln!(
                        out,
                        "start call, then steps {} rejected {} stale {} dropped {} lost {}; |e_p| {:.6e} -> {:.6e} m (ratio {:.3e}), seconds with a rise {}",
                        tally.steps,
                        tally.rejected,
                        tally.stale,
                        tally.dropped,
                        tally.lost,
                        first,
                        last,
                        last / first,
                        rises
                    );
                    let (used, available) = stack::high_water();
                    let _ = writeln!(
                        out,
                        "control task (steady-state steps only): at most {} ns from entry to command; stack used at most {} of {} bytes",
                        tally.busy_max_ns, used, available
                    );
                    #[cfg(feature = "qemu")]
                    let _ = writeln!(
                        out,
                        "period between control entries: {} to {} ns of virtual time",
                        tally.period_ns.0, tally.period_ns.1
                    );
                    let _ = writeln!(
                        out,
                        "{}",
                        if closed { "loop closed" } else { "FAIL: the loop did not close" }
                    );
                    exit(if closed { 0 } else { 1 })
                }
            }
        }
        let _ = writeln!(out, "E the control task went away");
        exit(1)
    }
}
