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

//!
//! ## The arm hash
//!
//! The arm's identity, which both roles announce (`arm_hash`): the same hash of the JSON value
//! that describes the arm as a robot *is* — its geometry and joint ranges, in the chain
//! description of `companion_core::chain` (URDF's joint frames):
//!
//! ```text
//! {"mount":  {"rotation": [R row by row, 9 numbers], "translation": [x, y, z]},
//!  "joints": [{"kind": "revolute" | "prismatic",
//!              "origin": {"rotation": [9], "translation": [3]},
//!              "axis": [3], "lower": q⁻, "upper": q⁺}, …],
//!  "tool":   {"rotation": [9], "translation": [3]}}
//! ```
//!
//! Every number as in the scenario hash, but a negative zero is written as zero (`−0.0` and
//! `0.0` are the same arm: a rotation computed from `rpy` gives the one, a matrix written by
//! hand the other), and a joint without limits (a URDF's `continuous`: `lower` −∞, `upper`
//! +∞) has `null` ones — JSON has no infinity — which add no line to the text.
//!
//! What the controller prefers (home position, velocity limits, gains) is not part of it: the
//! scenario hash covers that. A plant simulating a UR5 and a controller built for a Panda, or
//! for a UR5 mounted elsewhere, refuse each other by name ([`arm_hash`], [`arm_name`]).

use companion_core::{Chain, JointKind, Pose3};
use serde_json::{json, Value};

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

/// `x` with a negative zero written as zero: an arm's description is the same arm whichever
/// sign its zeros came out with (a rotation computed from `rpy` has `−0.0` where a matrix
/// written by hand has `0.0`).
fn num(x: f64) -> f64 {
    x + 0.0
}

fn frame(p: &Pose3<f64>) -> Value {
    let r = &p.rotation;
    let rows: Vec<f64> = (0..3).flat_map(|i| (0..3).map(move |j| num(r[(i, j)]))).collect();
    let t = &p.translation;
    json!({"rotation": rows, "translation": [num(t[0]), num(t[1]), num(t[2])]})
}

/// The JSON value an arm is hashed from (module docs).
pub fn arm_description<const N: usize>(chain: &Chain<f64, N>) -> Value {
    let joints: Vec<Value> = chain
        .joints
        .iter()
        .map(|j| {
            json!({
                "kind": match j.kind { JointKind::Revolute => "revolute", JointKind::Prismatic => "prismatic" },
                "origin": frame(&j.origin),
                "axis": [num(j.axis[0]), num(j.axis[1]), num(j.axis[2])],
                "lower": num(j.lower),
                "upper": num(j.upper),
            })
        })
        .collect();
    json!({"mount": frame(&chain.mount), "joints": joints, "tool": frame(&chain.tool)})
}

/// The arm hash of a chain: [`scenario_hash`] of [`arm_description`].
pub fn arm_hash<const N: usize>(chain: &Chain<f64, N>) -> u64 {
    scenario_hash(&arm_description(chain))
}

/// The name of a preset arm (`rpr`, `ur5`, `panda`) by its hash.
pub fn arm_name(hash: u64) -> Option<&'static str> {
    [
        ("rpr", arm_hash(&Chain::<f64, 3>::rpr())),
        ("ur5", arm_hash(&Chain::<f64, 6>::ur5())),
        ("panda", arm_hash(&Chain::<f64, 7>::panda())),
    ]
    .into_iter()
    .find_map(|(name, h)| (h == hash).then_some(name))
}

/// An arm hash in words: `ur5 (0x…)`, or the hash alone for another arm; `0 (not checked)`.
pub fn describe_arm(hash: u64) -> String {
    match (hash, arm_name(hash)) {
        (0, _) => "0 (not checked)".into(),
        (h, Some(name)) => format!("{name} ({h:#018x})"),
        (h, None) => format!("{h:#018x}"),
    }
}

/// FNV-1a, 64 bits (for the scenario hash and session ids).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    #[test]
    fn the_rpr_arm_is_described_as_documented() {
        // The paper's arm written by hand from docs/book/src/bridge.md (§8), as a bridge would.
        let id = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let at = |x: f64| json!({"rotation": id, "translation": [x, 0.0, 0.0]});
        let pi = core::f64::consts::PI;
        let joint = |kind: &str, axis: [f64; 3], lower: f64, upper: f64| json!({"kind": kind, "origin": at(0.0), "axis": axis, "lower": lower, "upper": upper});
        let by_hand = json!({
            "mount": at(0.4),
            "joints": [
                joint("revolute", [0.0, 0.0, 1.0], -pi / 3.0, pi / 3.0),
                joint("prismatic", [1.0, 0.0, 0.0], 0.0, 0.7),
                joint("revolute", [0.0, 0.0, 1.0], -pi / 2.0, pi / 2.0),
            ],
            "tool": at(0.15),
        });
        assert_eq!(canonical_text(&arm_description(&Chain::<f64, 3>::rpr())), canonical_text(&by_hand));
        assert_eq!(arm_hash(&Chain::<f64, 3>::rpr()), scenario_hash(&by_hand));
    }

    #[test]
    fn presets_have_distinct_named_hashes_and_the_home_is_not_part_of_them() {
        let (rpr, ur5, panda) = (
            arm_hash(&Chain::<f64, 3>::rpr()),
            arm_hash(&Chain::<f64, 6>::ur5()),
            arm_hash(&Chain::<f64, 7>::panda()),
        );
        assert!(rpr != ur5 && ur5 != panda && rpr != panda);
        assert_eq!(
            (arm_name(rpr), arm_name(ur5), arm_name(panda), arm_name(1)),
            (Some("rpr"), Some("ur5"), Some("panda"), None)
        );
        let mut moved = Chain::<f64, 6>::ur5();
        moved.joints[2].home += 0.1;
        moved.joints[2].max_velocity = 1.0;
        assert_eq!(arm_hash(&moved), ur5);
        moved.mount.translation[2] += 0.01;
        assert_ne!(arm_hash(&moved), ur5);
        assert!(describe_arm(ur5).starts_with("ur5 (0x") && describe_arm(0) == "0 (not checked)");
    }

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
