//! Prints the module cycles of crates given by their root files (exit code 1 if any):
//! `cargo run --release -p companion-tests --example module_cycles -- runtime/src/lib.rs`.
//! The test `module_cycles` runs the same check on every crate of the workspace.

use std::process::ExitCode;

use companion_tests::modgraph::{cycles, read_crate};

fn main() -> ExitCode {
    let mut any = false;
    for root in std::env::args().skip(1) {
        match read_crate(root.as_ref()) {
            Ok(m) => {
                let c = cycles(&m);
                println!("{root}: {} modules, {} cycles", m.len(), c.len());
                for x in &c {
                    println!("  {x}");
                }
                any |= !c.is_empty();
            }
            Err(e) => {
                eprintln!("{root}: {e}");
                any = true;
            }
        }
    }
    if any {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}
