//! The scenario hash: a check that plant and controller were started with the same
//! controller parameters, which any language can compute.
//!
//! The hash is FNV-1a (64 bits) of the **canonical text** of the controller's specification —
//! the `controller` object of the run's `scenario.json` (platform, scalar type, paper variant,
//! parameter overrides, transverse-function parameters, velocity limits), as JSON values:
//!
//! ```text
//! canonical(value, path):
//!   object  → canonical(member, path + "." + key) for every member   (no "." before the first key)
//!   array   → canonical(element, path + "." + index) for every element (index in decimal, from 0)
//!   null    → nothing
//!   boolean → path "=" ("true" | "false") "\n"
//!   number  → path "=" 16 lowercase hex digits of the number's IEEE-754 binary64 bits "\n"
//!   string  → path "=" the string's UTF-8 bytes "\n"
//! text = the lines sorted by their bytes, concatenated
//! hash = FNV-1a-64(text) (offset basis 0xcbf29ce484222325, prime 0x100000001b3); 0 becomes 1
//! ```
//!
//! For example `{"platform": "unicycle", "limits": null, "unicycle": {"epsilon_1": 0.2}}`
//! gives the text `platform=unicycle\nunicycle.epsilon_1=3fc999999999999a\n`.
//!
//! What it covers and why: the commands depend on these parameters and on what is on the
//! wire, nothing else (the hold periods and the lockstep flag, which change the joint guard,
//! are announced by the plant). The plant's own scenario (target, initial conditions,
//! imperfections, duration) is not covered: the controller sees it only through the
//! measurements. A plant that does not record the controller's parameters — a bridge to
//! hardware — sends 0 and the check is skipped; nothing the controller computes depends on
//! it. The companion plant sends the hash of the parameters it writes into `scenario.json`, so
//! that a run's files never describe a controller other than the one that ran.

use serde_json::Value;

use super::fnv1a;

/// The canonical text of a JSON value (see the module docs).
pub fn canonical_text(v: &Value) -> String {
    let mut lines = Vec::new();
    walk(v, "", &mut lines);
    lines.sort_unstable();
    lines.concat()
}

fn walk(v: &Value, path: &str, lines: &mut Vec<String>) {
    let join = |key: &str| if path.is_empty() { key.to_string() } else { format!("{path}.{key}") };
    match v {
        Value::Null => {}
        Value::Bool(b) => lines.push(format!("{path}={b}\n")),
        Value::Number(n) => {
            // serde_json numbers are f64, u64 or i64; all are read as binary64 here, as a JSON
            // reader of another language would.
            let x = n.as_f64().unwrap_or(f64::NAN);
            lines.push(format!("{path}={:016x}\n", x.to_bits()));
        }
        Value::String(s) => lines.push(format!("{path}={s}\n")),
        Value::Array(a) => {
            for (i, e) in a.iter().enumerate() {
                walk(e, &join(&i.to_string()), lines);
            }
        }
        Value::Object(o) => {
            for (k, e) in o {
                walk(e, &join(k), lines);
            }
        }
    }
}

/// The scenario hash of a JSON value: FNV-1a of its canonical text, never 0.
pub fn scenario_hash(v: &Value) -> u64 {
    fnv1a(canonical_text(v).as_bytes()).max(1)
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    #[test]
    fn the_documented_example() {
        let v = json!({"platform": "unicycle", "limits": null, "unicycle": {"epsilon_1": 0.2}});
        assert_eq!(canonical_text(&v), "platform=unicycle\nunicycle.epsilon_1=3fc999999999999a\n");
    }

    #[test]
    fn order_of_members_does_not_matter_and_values_do() {
        let a = json!({"b": [1.0, 2.5], "a": true, "c": {"x": "s"}});
        let b = json!({"c": {"x": "s"}, "a": true, "b": [1.0, 2.5]});
        assert_eq!(canonical_text(&a), canonical_text(&b));
        assert_eq!(canonical_text(&a), "a=true\nb.0=3ff0000000000000\nb.1=4004000000000000\nc.x=s\n");
        assert_eq!(scenario_hash(&a), scenario_hash(&b));
        assert_ne!(
            scenario_hash(&a),
            scenario_hash(&json!({"b": [1.0, 2.5000001], "a": true, "c": {"x": "s"}}))
        );
        // An integer and the same value written as a float are the same number.
        assert_eq!(scenario_hash(&json!({"k": 2})), scenario_hash(&json!({"k": 2.0})));
    }

    #[test]
    fn hash_is_fnv1a_of_the_text_and_never_zero() {
        let v = json!({"a": 1.0});
        assert_eq!(scenario_hash(&v), fnv1a(b"a=3ff0000000000000\n"));
        assert_eq!(scenario_hash(&json!(null)), fnv1a(b""));
    }
}
