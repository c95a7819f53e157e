//! The core's test suite: tests that would catch a wrong derivation.
//!
//! One test binary with one module per concern (one binary links and builds much faster
//! than ten); the allocation count lives apart in `tests/alloc.rs`, because its counting
//! global allocator must be alone in its process.
//!
//! | module | what it checks |
//! |---|---|
//! | [`lie`] | one conformance suite for SE(2) and SE(3): group law, `exp`/`log`, `Ad`, every Jacobian by differences, every small-angle branch |
//! | [`se2`] | group axioms, `d_γ` (2), `Ad` (5), velocities (3), (4), (6)–(9) by differences |
//! | [`spatial`] | §5: frames, `e_p` and every derivative by differences, the planar special case, the redundant solution, UR5 and Panda closed loops on every platform |
//! | [`tiago`] | a real robot's arm on the unicycle (PAL's TIAGo, 8 joints): run (a) settles from a home with reach both ways and a transverse function the wrist can follow; why not from a stretched home or with the paper's function |
//! | [`transverse`] | Lemma 1's determinant, Lemma 2's transversality, `H̄(α)` (13)–(15), (57)–(60), `∂ξ_f/∂α`, (59) |
//! | [`derivatives`] | every analytic derivative of the arm, `e_p`, `e_m`, `h_s1`, `h_s2`, `h_s` by differences |
//! | [`arms`] | arms as data: `rpr` is the paper's arm bit for bit; planar chains by differences; `ur5`, `panda` against their DH tables and published poses; validation |
//! | [`arm_law`] | `ė_m = G e_m` through whole steps (30), every platform and run, saturated or not |
//! | [`heading`] | the heading filter (beyond the paper): the filtered target's body velocity by differences, nothing changed while the target does not turn, the lag to second order, a target turning in place no longer drags the platform |
//! | [`hold`] | the hold-aware discretisation: third-order residual over a hold, delays predicted exactly, no lock-out, bounded state, turn bound |
//! | [`platform_law`] | (36)–(37) with every weight and pre-compensation; the state update; initialisation |
//! | [`saturation`] | one common factor, direction kept, limits met |
//! | [`acceleration`] | no command changes faster than its limit (closed loop, every platform, f32 and f64), direction kept, joints never at a limit, the conflict with the guard, refusals, the start call, the in-place step |
//! | [`closed_loop`] | exact plant (RK4): `log ‖e_m‖` slope −3; `h_s` non-increasing in run (a) |
//! | [`robustness`] | arbitrary bits never panic nor give a non-finite command; typed errors; state kept |
//! | [`precision`] | f32 against f64, single steps and closed loop |
//! | [`params`] | every `Rule`, the paper preset and its warning |
//!
//! The references in [`common`] are written independently of the core, from the paper.

#[path = "../common/mod.rs"]
mod common;

mod acceleration;
mod arm_law;
mod arms;
mod closed_loop;
mod derivatives;
mod heading;
mod hold;
mod joint_guard;
mod lie;
mod params;
mod platform_law;
mod precision;
mod robustness;
mod saturation;
mod se2;
mod spatial;
mod tiago;
mod transverse;
