//! The checked-in C header is what cbindgen generates from this crate today: a change of the
//! C ABI that is not regenerated into `include/companion.h` fails `cargo test` (and CI).
//!
//! Regenerate with `COMPANION_FFI_BLESS=1 cargo test --release -p companion-ffi --test header`.

use std::path::Path;

const REGENERATE: &str = "COMPANION_FFI_BLESS=1 cargo test --release -p companion-ffi --test header";

fn generate() -> String {
    let crate_dir = env!("CARGO_MANIFEST_DIR");
    let config = cbindgen::Config::from_file(Path::new(crate_dir).join("cbindgen.toml"))
        .expect("cbindgen.toml parses");
    let bindings = cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header");
    let mut out = Vec::new();
    bindings.write(&mut out);
    String::from_utf8(out).expect("the header is UTF-8")
}

#[test]
fn checked_in_header_is_current() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("include").join("companion.h");
    let fresh = generate();
    if std::env::var_os("COMPANION_FFI_BLESS").is_some() {
        std::fs::write(&path, &fresh).expect("write include/companion.h");
        eprintln!("wrote {}", path.display());
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    if checked_in != fresh {
        let first = checked_in
            .lines()
            .zip(fresh.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| checked_in.lines().count().min(fresh.lines().count()));
        panic!(
            "ffi/include/companion.h is stale: it differs from what cbindgen generates from ffi/src \
             (first difference at line {}).\n  checked in: {:?}\n  generated:  {:?}\nRegenerate it with:\n  {REGENERATE}",
            first + 1,
            checked_in.lines().nth(first).unwrap_or("<end of file>"),
            fresh.lines().nth(first).unwrap_or("<end of file>"),
        );
    }
}

#[test]
fn header_declares_the_c_api() {
    let h = generate();
    for item in [
        "companion_f64_init",
        "companion_f32_init",
        "companion_f64_init_paper",
        "companion_f64_params_paper",
        "companion_f64_step",
        "companion_f32_step",
        "companion_status_name",
        "COMPANION_CONTROLLER_SIZE",
        "COMPANION_CONTROLLER_ALIGN",
        "COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q2 = 221",
        "COMPANION_STATUS_PARAM_NOT_POSITIVE = 101",
        "COMPANION_PLATFORM_CAR = 1",
    ] {
        assert!(h.contains(item), "the generated header lacks `{item}`:\n{h}");
    }
}
