//! The closed-loop fuzz (`companion_tests::fuzz`) at the size of the test suite: a million
//! steps of every platform, scalar type, run and discretisation with garbage bursts. CI runs
//! it at ten million (`cargo run --release -p companion-tests --example fuzz`).

use companion_tests::fuzz::{fuzz, FuzzConfig, Garbage};

#[test]
fn the_controller_always_comes_back() {
    let report = fuzz(&FuzzConfig { steps: 1_000_000, seed: 7, ..FuzzConfig::default() }, &|_| {});
    eprintln!("{report}");
    assert!(report.passed(), "{report}");
    assert_eq!(report.steps, 1_000_000);
    // The fuzz did fuzz: every kind of garbage went in, some accepted, most rejected.
    for kind in Garbage::ALL {
        assert!(report.garbage.get(&kind).copied().unwrap_or(0) > 100, "{kind:?} barely injected: {report}");
    }
    assert!(report.bursts > 1_000, "{report}");
    assert!(report.garbage_accepted > 0 && report.garbage_accepted < report.garbage_steps(), "{report}");
    // Every valid measurement is accepted — after a burst, the very first one. (The plant is
    // reset whenever accepted garbage drove it out of the law's domain, so a valid
    // measurement is always inside it.)
    assert!(report.valid_rejected.is_empty(), "{report}");
    assert_eq!(report.recovered_at_once, report.recovery_checks, "{report}");
    assert!(report.recovery_checks > 1_000, "{report}");
}
