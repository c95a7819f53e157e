//! No module of any crate of the workspace depends on another in a cycle (see
//! `companion_tests::modgraph` for what counts): dependencies point one way, so that each
//! layer can be read, tested and changed without the ones above it.

use std::path::Path;

use companion_tests::modgraph::{cycles, layer_violations, read_crate, Layers};

#[test]
fn no_crate_has_a_module_cycle() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let crates = [
        "core/src/lib.rs",
        "sim-plant/src/lib.rs",
        "runtime/src/lib.rs",
        "runtime/src/main.rs",
        "benches/src/lib.rs",
        "tests/src/lib.rs",
        "python/src/lib.rs",
    ];
    let mut found = Vec::new();
    let mut modules = 0;
    for c in crates {
        let m = read_crate(&root.join(c)).unwrap_or_else(|e| panic!("{c}: {e}"));
        modules += m.len();
        found.extend(cycles(&m).into_iter().map(|x| format!("{c}: {x}")));
    }
    // The runtime alone has dozens of modules: the reader found them.
    assert!(modules > 50, "only {modules} modules read");
    assert!(found.is_empty(), "module cycles:\n{}", found.join("\n"));
}

/// The runtime's five layers (its `lib.rs` says what each holds): a layer uses only the ones
/// listed before it, and `domain` and `sys` use nothing of each other.
const RUNTIME_LAYERS: Layers<'static> = &[
    ("domain", &[]),
    ("sys", &[]),
    ("transport", &["sys"]),
    ("run", &["domain", "sys", "transport"]),
    ("study", &["domain", "sys", "transport", "run"]),
];

#[test]
fn runtime_layers_point_one_way() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../runtime/src/lib.rs");
    let m = read_crate(&root).unwrap_or_else(|e| panic!("{e}"));
    let found = layer_violations(&m, RUNTIME_LAYERS);
    assert!(found.is_empty(), "dependencies against the runtime's layers:\n{}", found.join("\n"));
}
