//! Which velocity and acceleration limits a run runs with, and where each came from.
//!
//! Two sources can set a limit: the config file (`[velocity_limits]`, `[acceleration_limits]`
//! — a robot file carries its base's limits there) and a named preset (`--limits tiago`,
//! `--limits realistic`, Python's `limits='tiago'`). They compose key by key, **the stricter
//! value winning**: a preset never loosens what the file sets, and a key only one of them sets
//! (the file's `alpha_rate`, its joints' accelerations) is kept. `--limits none` is the one
//! exception: the paper's runs, no limit at all, the file's dropped (and recorded as dropped).
//! Without a file or a preset, the car runs with realistic velocity limits (its unsaturated
//! Lemma 2 gains can diverge, SPEC §3) and the other platforms with none.
//!
//! ```text
//! limit(key) = min(file(key), preset(key))      an unset key is +∞; no key set: no limit
//! ```
//!
//! [`Resolved::record`] lists every limit that ran with its source, for `scenario.json`.

use companion_core::PlatformKind;
use serde::Serialize;

use super::LimitsChoice;
use crate::domain::controller::{AccelerationConfig, LimitsConfig};

/// One limit that ran: its key, value and source.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LimitSource {
    /// The key as in a config file: `velocity_limits.forward`, `acceleration_limits.joints[2]`.
    pub key: String,
    /// The value that ran, in the key's unit (m/s, rad/s, m/s², rad/s², 1/(m·s)).
    pub value: f64,
    /// Where it came from: `config file`, `limits tiago` (or `realistic`, `custom`), both
    /// (`config file = limits tiago`: equal values), or `default for the car`.
    pub from: String,
    /// The other source's value for the key, when both set it and it was looser.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub looser: Option<f64>,
}

/// The limits of a run and their sources (`scenario.json`'s `limits`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LimitsRecord {
    /// Every limit that ran.
    pub applied: Vec<LimitSource>,
    /// The config file's keys that `--limits none` dropped.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dropped: Vec<String>,
}

impl LimitsRecord {
    /// Whether the run had no limit and dropped none (the paper's runs: not written).
    pub fn is_empty(&self) -> bool {
        self.applied.is_empty() && self.dropped.is_empty()
    }
}

/// The limits a run runs with.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    /// Velocity limits (`None`: none).
    pub velocity: Option<LimitsConfig>,
    /// Acceleration limits (`None`: none).
    pub acceleration: Option<AccelerationConfig>,
    /// Where each came from.
    pub record: LimitsRecord,
}

/// The name of a preset, as its source is written.
fn preset_name(choice: LimitsChoice) -> &'static str {
    match choice {
        LimitsChoice::Unlimited => "none",
        LimitsChoice::Realistic => "realistic",
        LimitsChoice::Tiago => "tiago",
        LimitsChoice::Custom(_) => "custom",
    }
}

/// Merges the keys of two sources into one value per key, recording the sources.
struct Merge<'a> {
    /// The preset's source text (`limits tiago`).
    preset: &'a str,
    record: Vec<LimitSource>,
}

impl Merge<'_> {
    /// The stricter of the file's and the preset's value for `key` (a file value that is not
    /// a number wins, so that validation refuses it by name).
    fn key(&mut self, key: String, file: Option<f64>, preset: Option<f64>) -> Option<f64> {
        let (value, from, looser) = match (file, preset) {
            (None, None) => return None,
            (Some(f), None) => (f, "config file".to_string(), None),
            (None, Some(p)) => (p, self.preset.to_string(), None),
            (Some(f), Some(p)) if f.is_nan() || f < p => (f, "config file".to_string(), Some(p)),
            (Some(f), Some(p)) if f == p => (f, format!("config file = {}", self.preset), None),
            (Some(f), Some(p)) => (p, self.preset.to_string(), Some(f)),
        };
        self.record.push(LimitSource { key, value, from, looser });
        Some(value)
    }

    fn velocity(&mut self, file: Option<LimitsConfig>, preset: Option<LimitsConfig>) -> Option<LimitsConfig> {
        if file.is_none() && preset.is_none() {
            return None;
        }
        let (f, p) = (file.unwrap_or_default(), preset.unwrap_or_default());
        let k = |name: &str| format!("velocity_limits.{name}");
        Some(LimitsConfig {
            forward: self.key(k("forward"), f.forward, p.forward),
            lateral: self.key(k("lateral"), f.lateral, p.lateral),
            angular: self.key(k("angular"), f.angular, p.angular),
            alpha_rate: self.key(k("alpha_rate"), f.alpha_rate, p.alpha_rate),
            steering_rate: self.key(k("steering_rate"), f.steering_rate, p.steering_rate),
        })
    }

    fn acceleration(
        &mut self,
        file: Option<&AccelerationConfig>,
        preset: Option<&AccelerationConfig>,
    ) -> Option<AccelerationConfig> {
        if file.is_none() && preset.is_none() {
            return None;
        }
        let none = AccelerationConfig::default();
        let (f, p) = (file.unwrap_or(&none), preset.unwrap_or(&none));
        let k = |name: &str| format!("acceleration_limits.{name}");
        let forward = self.key(k("forward"), f.forward, p.forward);
        let lateral = self.key(k("lateral"), f.lateral, p.lateral);
        let angular = self.key(k("angular"), f.angular, p.angular);
        // Per joint, when both give as many values; otherwise the file's array as it is (its
        // count is checked against the arm's later) or the preset's.
        let joints = match (&f.joints, &p.joints) {
            (None, None) => None,
            (Some(a), Some(b)) if a.len() == b.len() => Some(
                a.iter()
                    .zip(b)
                    .enumerate()
                    .map(|(i, (x, y))| self.key(format!("{}[{i}]", k("joints")), Some(*x), Some(*y)))
                    .map(|x| x.unwrap_or(f64::INFINITY))
                    .collect(),
            ),
            (Some(a), _) => {
                for (i, x) in a.iter().enumerate() {
                    self.key(format!("{}[{i}]", k("joints")), Some(*x), None);
                }
                Some(a.clone())
            }
            (None, Some(b)) => {
                for (i, x) in b.iter().enumerate() {
                    self.key(format!("{}[{i}]", k("joints")), None, Some(*x));
                }
                Some(b.clone())
            }
        };
        Some(AccelerationConfig { forward, lateral, angular, joints })
    }
}

/// The keys a config file's limits set (for the record of what `--limits none` dropped).
fn file_keys(v: Option<LimitsConfig>, a: Option<&AccelerationConfig>) -> Vec<String> {
    let mut keys = Vec::new();
    if let Some(v) = v {
        for (name, x) in [
            ("forward", v.forward),
            ("lateral", v.lateral),
            ("angular", v.angular),
            ("alpha_rate", v.alpha_rate),
            ("steering_rate", v.steering_rate),
        ] {
            if x.is_some() {
                keys.push(format!("velocity_limits.{name}"));
            }
        }
    }
    if let Some(a) = a {
        for (name, x) in [("forward", a.forward), ("lateral", a.lateral), ("angular", a.angular)] {
            if x.is_some() {
                keys.push(format!("acceleration_limits.{name}"));
            }
        }
        if a.joints.is_some() {
            keys.push("acceleration_limits.joints".to_string());
        }
    }
    keys
}

/// The limits of a run on `platform` with the config file's `file_velocity` and
/// `file_acceleration` and the preset `choice` (module docs).
pub fn resolve(
    choice: Option<LimitsChoice>,
    file_velocity: Option<LimitsConfig>,
    file_acceleration: Option<&AccelerationConfig>,
    platform: PlatformKind,
) -> Resolved {
    let (preset_velocity, preset_acceleration, source) = match choice {
        Some(LimitsChoice::Unlimited) => {
            let dropped = file_keys(file_velocity, file_acceleration);
            let record = LimitsRecord { applied: Vec::new(), dropped };
            return Resolved { velocity: None, acceleration: None, record };
        }
        None if file_velocity.is_none() && platform == PlatformKind::Car => {
            (Some(LimitsConfig::realistic()), None, "default for the car".to_string())
        }
        None => (None, None, String::new()),
        Some(c @ LimitsChoice::Realistic) => (Some(LimitsConfig::realistic()), None, preset_source(c)),
        Some(c @ LimitsChoice::Tiago) => {
            (Some(LimitsConfig::tiago()), Some(AccelerationConfig::tiago()), preset_source(c))
        }
        Some(c @ LimitsChoice::Custom(l)) => (Some(l), None, preset_source(c)),
    };
    let mut m = Merge { preset: &source, record: Vec::new() };
    let velocity = m.velocity(file_velocity, preset_velocity);
    let acceleration = m.acceleration(file_acceleration, preset_acceleration.as_ref());
    Resolved { velocity, acceleration, record: LimitsRecord { applied: m.record, dropped: Vec::new() } }
}

fn preset_source(c: LimitsChoice) -> String {
    format!("limits {}", preset_name(c))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> crate::domain::scenario::ConfigFile {
        toml::from_str(text).expect("TOML")
    }

    fn source<'a>(r: &'a Resolved, key: &str) -> &'a LimitSource {
        r.record.applied.iter().find(|s| s.key == key).unwrap_or_else(|| panic!("{key} in {:?}", r.record))
    }

    /// The stricter value wins per key, a key only one source sets is kept, and each limit's
    /// source is recorded (with the looser value it beat).
    #[test]
    fn the_stricter_value_wins_per_key_and_each_keeps_its_source() {
        let f = file(
            "[velocity_limits]\nforward = 0.5\nangular = 3.0\nalpha_rate = 1.5\n\
             [acceleration_limits]\nforward = 2.0\nangular = 2.09\njoints = [1.0, 2.0, 3.0]\n",
        );
        let r = resolve(
            Some(LimitsChoice::Tiago),
            f.velocity_limits,
            f.acceleration_limits.as_ref(),
            PlatformKind::Unicycle,
        );
        let v = r.velocity.expect("velocity limits");
        assert_eq!((v.forward, v.angular, v.alpha_rate), (Some(0.5), Some(2.09), Some(1.5)));
        assert_eq!((v.lateral, v.steering_rate), (None, None));
        let a = r.acceleration.clone().expect("acceleration limits");
        assert_eq!((a.forward, a.angular, a.lateral), (Some(1.0), Some(2.09), None));
        assert_eq!(a.joints, Some(vec![1.0, 2.0, 3.0]));
        let forward = source(&r, "velocity_limits.forward");
        assert_eq!((forward.from.as_str(), forward.looser), ("config file", Some(1.0)));
        let angular = source(&r, "velocity_limits.angular");
        assert_eq!((angular.from.as_str(), angular.value, angular.looser), ("limits tiago", 2.09, Some(3.0)));
        assert_eq!(source(&r, "velocity_limits.alpha_rate").from, "config file");
        assert_eq!(source(&r, "acceleration_limits.forward").from, "limits tiago");
        assert_eq!(source(&r, "acceleration_limits.angular").from, "config file = limits tiago");
        assert_eq!(source(&r, "acceleration_limits.joints[2]").value, 3.0);
        assert_eq!(r.record.applied.len(), 8, "{:?}", r.record);
        assert!(r.record.dropped.is_empty());
    }

    /// A preset alone, a file alone, nothing: the car's default and nothing else.
    #[test]
    fn one_source_alone_and_the_cars_default() {
        let t = resolve(Some(LimitsChoice::Tiago), None, None, PlatformKind::Unicycle);
        assert_eq!(t.velocity, Some(LimitsConfig::tiago()));
        assert_eq!(t.acceleration, Some(AccelerationConfig::tiago()));
        assert!(t.record.applied.iter().all(|s| s.from == "limits tiago" && s.looser.is_none()));
        assert_eq!(t.record.applied.len(), 4);
        let f = file("[velocity_limits]\nforward = 0.7\n");
        let only = resolve(None, f.velocity_limits, None, PlatformKind::Car);
        assert_eq!(only.velocity, f.velocity_limits, "a car's file replaces its default");
        assert_eq!(source(&only, "velocity_limits.forward").from, "config file");
        let car = resolve(None, None, None, PlatformKind::Car);
        assert_eq!(car.velocity, Some(LimitsConfig::realistic()));
        assert!(car.record.applied.iter().all(|s| s.from == "default for the car"));
        let none = resolve(None, None, None, PlatformKind::Omni);
        assert_eq!((none.velocity, none.acceleration), (None, None));
        assert!(none.record.is_empty());
        // Realistic velocity limits merge with the file's and keep its accelerations.
        let f = file("[velocity_limits]\nalpha_rate = 0.5\n[acceleration_limits]\nforward = 0.5\n");
        let r = resolve(
            Some(LimitsChoice::Realistic),
            f.velocity_limits,
            f.acceleration_limits.as_ref(),
            PlatformKind::Car,
        );
        let real = LimitsConfig::realistic();
        let v = r.velocity.expect("limits");
        assert_eq!(v.forward, real.forward);
        assert_eq!((real.alpha_rate, v.alpha_rate), (Some(10.0), Some(0.5)));
        assert_eq!(r.acceleration.and_then(|a| a.forward), Some(0.5));
    }

    /// `--limits none` drops everything, the file's limits too, and says which.
    #[test]
    fn none_drops_the_files_limits_and_records_them() {
        let f =
            file("[velocity_limits]\nalpha_rate = 1.5\n[acceleration_limits]\njoints = [1.0, 1.0, 1.0]\n");
        let r = resolve(
            Some(LimitsChoice::Unlimited),
            f.velocity_limits,
            f.acceleration_limits.as_ref(),
            PlatformKind::Car,
        );
        assert_eq!((r.velocity, r.acceleration), (None, None));
        assert!(r.record.applied.is_empty());
        assert_eq!(r.record.dropped, ["velocity_limits.alpha_rate", "acceleration_limits.joints"]);
    }

    /// A file's value that is not a number is kept (validation refuses it by name), and a
    /// joint array of another length than the preset's stays the file's.
    #[test]
    fn a_bad_file_value_is_not_hidden_by_a_preset() {
        let v = LimitsConfig { forward: Some(f64::NAN), ..LimitsConfig::default() };
        let r = resolve(Some(LimitsChoice::Tiago), Some(v), None, PlatformKind::Unicycle);
        assert!(r.velocity.and_then(|l| l.forward).is_some_and(f64::is_nan));
        let preset = AccelerationConfig { joints: Some(vec![1.0; 2]), ..AccelerationConfig::default() };
        let mine = AccelerationConfig { joints: Some(vec![0.5; 3]), ..AccelerationConfig::default() };
        let mut m = Merge { preset: "limits custom", record: Vec::new() };
        let a = m.acceleration(Some(&mine), Some(&preset)).expect("limits");
        assert_eq!(a.joints, Some(vec![0.5; 3]));
        assert!(m.record.iter().all(|s| s.from == "config file"));
    }
}
