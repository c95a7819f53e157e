//! The space an exploration samples: initial conditions and controller parameters, each a
//! fixed value or a range drawn uniformly, read from a TOML file (`--space FILE`) and checked
//! before any simulation runs.
//!
//! ```toml
//! [initial]                      # each key: a number, or [low, high]
//! distance = [0.5, 6.0]          # m: ‖p_bd(0)‖, the target's distance from the platform
//! bearing = [-3.14159, 3.14159]  # rad: where the target is, seen from the platform
//! heading = [-3.14159, 3.14159]  # rad: θ_bd(0), the target's heading relative to the platform
//! q1 = 0.0                       # rad    (joints strictly inside their limits)
//! q2 = [0.2, 0.6]                # m
//! q3 = 0.0                       # rad
//! alpha_1 = [0.0, 6.2832]        # rad: α(0) of the transverse function
//! alpha_2 = 0.0                  # rad (car only)
//! steering = 0.0                 # 1/m: the car's ξ(0); omitted: ξ_f(α(0))
//!
//! [parameters]                   # knobs (see `companion_runtime::study::knobs`)
//! epsilon = [0.05, 0.3]
//! stroke = [0.7, 1.2]
//!
//! [map]                          # the success map's axes: two variables drawn from ranges
//! x = "distance"
//! y = "heading"
//! bins = [8, 12]
//!
//! [judge]                        # how a run is classified (`trial::Judge`)
//! tolerance = 1e-3
//! window = 5.0                   # s (default: 5, or the whole run if shorter)
//! divergence = 100.0
//! track_after = 20.0             # s: the tracked fraction from here (default: T/2)
//! ```
//!
//! An initial value the file does not give is the scenario's own (the trajectory's
//! `r_bd(0)`, `q(0)`; `α(0) = 0`); a parameter it does not give is the scenario's.
//!
//! With a spatial arm (`companion explore --arm`) the start is `sim --arm`'s (the platform
//! at the origin, the arm at home, the lifted target where the arm holds it): of `[initial]`
//! only `alpha_1` and `alpha_2` may be given, and the other columns are `NaN`. The knobs
//! `joint_speed` and `reach` scale the arm, `damping_below` sets its law's damping onset;
//! `gain` and `stroke` are the planar arm's and refused (`lambda` filters either arm's
//! weight).
//! Unknown keys, empty or reversed ranges, joints outside their limits and parameters the
//! law rejects are errors. Parameters are checked at every corner of their box: each rule is
//! monotone in each parameter or, like Lemma 2's `6η₂η₃ − 8η₃ − η₁η₂ > 0`, multilinear in
//! them, so a box whose corners are valid is valid throughout.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::domain::plant_setup::PlantSetupError;
use crate::domain::scenario::{Scenario, ScenarioBuilder, ScenarioError};
use crate::run::spatial::{self, SpatialRunError, SpatialScenario};
use crate::study::knobs::{self, ArmKind, Knob};
use crate::study::trial::{Judge, SpatialSetup};

/// Why a space file cannot be read, or the space it describes cannot be explored; every text
/// is the message the command line prints.
#[derive(Debug, thiserror::Error)]
pub enum SpaceError {
    /// The space file cannot be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The space file is not TOML of a space file's shape.
    #[error("in space file {}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: toml::de::Error,
    },
    /// The base scenario is invalid.
    #[error("the scenario")]
    Scenario(#[source] ScenarioError),
    /// The base scenario's plant, whose start the space is drawn around, cannot be built.
    #[error(transparent)]
    Start(#[from] PlantSetupError),
    /// The scenario at the space's shortest stroke is invalid.
    #[error(transparent)]
    Stroke(ScenarioError),
    /// A fixed value is not finite.
    #[error("`{name}` = {value} must be finite")]
    NotFinite {
        /// The variable.
        name: String,
        /// Its value.
        value: f64,
    },
    /// A range has an end that is not finite.
    #[error("`{name}` = [{lo}, {hi}]: both ends must be finite")]
    EndNotFinite {
        /// The variable.
        name: String,
        /// The low end.
        lo: f64,
        /// The high end.
        hi: f64,
    },
    /// A range is empty or reversed.
    #[error("`{name}` = [{lo}, {hi}] is an empty range: the low end must be below the high end")]
    EmptyRange {
        /// The variable.
        name: String,
        /// The low end.
        lo: f64,
        /// The high end.
        hi: f64,
    },
    /// The distance can be negative.
    #[error("`distance` must be >= 0 m, got {0}")]
    NegativeDistance(f64),
    /// A key of `[parameters]` is not a knob of the platform: the reason.
    #[error("[parameters]: {0}")]
    Knob(String),
    /// The law rejects the parameters at a corner of the box: the corner and the reason.
    #[error("the law rejects the parameters at a corner of the space ({at}): {why}")]
    Corner {
        /// The corner, `knob = value` joined by commas.
        at: String,
        /// The law's reason.
        why: ScenarioError,
    },
    /// An `[initial]` variable a spatial run's start does not have.
    #[error(
        "[initial]: `{0}` is not available with a spatial arm (--arm): its start is the platform at the \
         origin with the arm at home; only alpha_1 and alpha_2 may be drawn"
    )]
    SpatialInitial(&'static str),
    /// The spatial run at a corner of the box cannot run (its arm, law, target or plant).
    #[error("the spatial run at a corner of the space ({at}): {why}")]
    SpatialCorner {
        /// The corner, `knob = value` joined by commas.
        at: String,
        /// Why.
        why: Box<PointError>,
    },
    /// A joint's range reaches its limits.
    #[error("`q{joint}` = {value:?} must lie strictly inside the joint's limits ({lower}, {upper})")]
    JointRange {
        /// The joint, from 1.
        joint: usize,
        /// Its value in the space.
        value: Value,
        /// Its lower limit.
        lower: f64,
        /// Its upper limit.
        upper: f64,
    },
    /// No variable is drawn from a range.
    #[error("the space draws no variable: give at least one range")]
    NothingDrawn,
    /// A map axis is not a drawn variable.
    #[error("map axis `{0}` must be a variable of the space drawn from a range")]
    MapAxis(String),
    /// The map's two axes are the same.
    #[error("the map's two axes must differ (both are `{0}`)")]
    SameAxes(String),
    /// A map's bin count is outside 1 to 100.
    #[error("map bins must be 1 to 100 each, got {0:?}")]
    MapBins([usize; 2]),
    /// `judge.track_after` is outside the run.
    #[error("judge.track_after must be in [0, duration = {duration} s), got {value}")]
    TrackAfter {
        /// The run's duration (s).
        duration: f64,
        /// The value given.
        value: f64,
    },
    /// `judge.tolerance` is not positive.
    #[error("judge.tolerance must be > 0, got {0}")]
    Tolerance(f64),
    /// `judge.window` is outside the run.
    #[error("judge.window must be in (0, duration = {duration} s], got {value}")]
    Window {
        /// The run's duration (s).
        duration: f64,
        /// The value given.
        value: f64,
    },
    /// `judge.divergence` is not above the tolerance.
    #[error("judge.divergence must be finite and > tolerance, got {0}")]
    Divergence(f64),
}

/// A value of the space: fixed, or drawn uniformly from `[low, high)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Value {
    /// One value.
    Fixed(f64),
    /// `[low, high]`, drawn uniformly.
    Range([f64; 2]),
}

impl Value {
    /// The value at `u ∈ [0, 1)`.
    pub fn at(self, u: f64) -> f64 {
        match self {
            Self::Fixed(v) => v,
            Self::Range([lo, hi]) => lo + u * (hi - lo),
        }
    }

    /// `(low, high)`; a fixed value is both.
    pub fn bounds(self) -> (f64, f64) {
        match self {
            Self::Fixed(v) => (v, v),
            Self::Range([lo, hi]) => (lo, hi),
        }
    }

    /// Whether it is drawn.
    pub fn is_range(self) -> bool {
        matches!(self, Self::Range(_))
    }

    fn check(self, name: &str) -> Result<(), SpaceError> {
        let name = name.to_string();
        match self {
            Self::Fixed(value) if !value.is_finite() => Err(SpaceError::NotFinite { name, value }),
            Self::Range([lo, hi]) if !(lo.is_finite() && hi.is_finite()) => {
                Err(SpaceError::EndNotFinite { name, lo, hi })
            }
            Self::Range([lo, hi]) if lo >= hi => Err(SpaceError::EmptyRange { name, lo, hi }),
            _ => Ok(()),
        }
    }
}

/// The initial-condition variables, in the order of the columns and of the draws.
pub const INITIAL: [&str; 9] =
    ["distance", "bearing", "heading", "q1", "q2", "q3", "alpha_1", "alpha_2", "steering"];

/// The `[initial]` table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpace {
    /// `‖p_bd(0)‖` (m).
    pub distance: Option<Value>,
    /// The target's direction seen from the platform (rad).
    pub bearing: Option<Value>,
    /// `θ_bd(0)` (rad).
    pub heading: Option<Value>,
    /// `q₁(0)` (rad).
    pub q1: Option<Value>,
    /// `q₂(0)` (m).
    pub q2: Option<Value>,
    /// `q₃(0)` (rad).
    pub q3: Option<Value>,
    /// `α₁(0)` (rad).
    pub alpha_1: Option<Value>,
    /// `α₂(0)` (rad).
    pub alpha_2: Option<Value>,
    /// The car's `ξ(0)` (1/m); `None`: `ξ_f(α(0))`.
    pub steering: Option<Value>,
}

impl InitialSpace {
    fn get(&self, i: usize) -> Option<Value> {
        [
            self.distance,
            self.bearing,
            self.heading,
            self.q1,
            self.q2,
            self.q3,
            self.alpha_1,
            self.alpha_2,
            self.steering,
        ][i]
    }
}

/// The `[map]` table: the success map's axes and bins.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    /// The horizontal axis: a variable drawn from a range.
    pub x: String,
    /// The vertical axis (none: a one-row map).
    pub y: Option<String>,
    /// Bins along x and y (1 to 100 each).
    #[serde(default = "default_bins")]
    pub bins: [usize; 2],
}

fn default_bins() -> [usize; 2] {
    [8, 12]
}

/// A space file as written.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpaceFile {
    /// Initial conditions.
    #[serde(default)]
    pub initial: InitialSpace,
    /// Knobs by name.
    #[serde(default)]
    pub parameters: BTreeMap<String, Value>,
    /// The success map.
    pub map: Option<MapSpec>,
    /// The classification.
    pub judge: Option<JudgeFile>,
}

/// The `[judge]` table (omitted keys: `trial::Judge`'s defaults).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JudgeFile {
    /// `‖e_p‖` below this is tracked.
    pub tolerance: Option<f64>,
    /// The final window (s) over which a converged run stays tracked.
    pub window: Option<f64>,
    /// `‖e_p‖` above this stops the run as diverged.
    pub divergence: Option<f64>,
    /// The tracked fraction counts from this time (s); default: half the duration.
    pub track_after: Option<f64>,
}

impl SpaceFile {
    /// Reads a space file.
    ///
    /// # Errors
    /// The file cannot be read or is not TOML of this shape (unknown keys included).
    pub fn load(path: &Path) -> Result<Self, SpaceError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| SpaceError::Read { path: path.to_path_buf(), source })?;
        toml::from_str(&text).map_err(|source| SpaceError::Parse { path: path.to_path_buf(), source })
    }

    /// The default space: starts around the target — any distance from 0.5 to 6 m, any
    /// bearing, any relative heading; joints, `α(0)` and the parameters as the scenario has
    /// them; the map over distance and heading.
    pub fn around_the_target() -> Self {
        Self {
            initial: InitialSpace {
                distance: Some(Value::Range([0.5, 6.0])),
                bearing: Some(Value::Range([-PI, PI])),
                heading: Some(Value::Range([-PI, PI])),
                ..InitialSpace::default()
            },
            parameters: BTreeMap::new(),
            map: None,
            judge: None,
        }
    }
}

/// A checked space: every variable's value, the knobs, the map and the judge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Space {
    /// The initial variables, in [`INITIAL`] order; `steering` may be `None` (matched).
    pub initial: [Option<Value>; 9],
    /// The knobs with their values, in `knobs::ALL` order.
    pub parameters: Vec<(Knob, Value)>,
    /// The map.
    pub map: MapSpec,
    /// The classification.
    pub judge: Judge,
}

/// One sample's values: the start and the knobs.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// The initial variables in [`INITIAL`] order (`steering` NaN when matched).
    pub initial: [f64; 9],
    /// The knobs' values, as [`Space::parameters`].
    pub parameters: Vec<(Knob, f64)>,
}

impl Space {
    /// Checks `file` against the scenario `builder` makes (platform, joint limits, the law's
    /// rules at every corner of the parameter box) before anything runs.
    ///
    /// # Errors
    /// An unknown key, an empty, reversed or non-finite range, joints outside their limits, a
    /// parameter of another platform, a corner of the box the law rejects (named, with the
    /// rule), map axes that are not ranges, or a bad judge.
    pub fn check(file: &SpaceFile, builder: &ScenarioBuilder) -> Result<Self, SpaceError> {
        Self::check_for(file, builder, None)
    }

    /// [`check`](Self::check), for the spatial arm `arm` if given: its start, its knobs, the
    /// spatial run at every corner of the box.
    ///
    /// # Errors
    /// As [`check`](Self::check); with an arm, an `[initial]` variable other than α, a planar
    /// arm's knob, or a corner whose spatial run cannot be built.
    pub fn check_for(
        file: &SpaceFile,
        builder: &ScenarioBuilder,
        arm: Option<&SpatialSetup>,
    ) -> Result<Self, SpaceError> {
        let base = builder.clone().build().map_err(SpaceError::Scenario)?;
        let platform = base.controller.platform;
        let start = match arm {
            None => base_start(&base)?,
            Some(_) => {
                let a = base.controller.initial_alpha;
                [f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN, a[0], a[1], f64::NAN]
            }
        };
        let mut initial = [None; 9];
        for (i, name) in INITIAL.iter().enumerate() {
            let v = file.initial.get(i);
            if let Some(v) = v {
                if arm.is_some() && !matches!(*name, "alpha_1" | "alpha_2") {
                    return Err(SpaceError::SpatialInitial(name));
                }
                v.check(name)?;
            }
            initial[i] = match (i, v) {
                (8, v) => v,
                (_, Some(v)) => Some(v),
                (_, None) if start[i].is_nan() => None,
                (_, None) => Some(Value::Fixed(start[i])),
            };
        }
        if let Some(Value::Range([lo, _]) | Value::Fixed(lo)) = initial[0] {
            if lo < 0.0 {
                return Err(SpaceError::NegativeDistance(lo));
            }
        }
        let mut parameters = Vec::new();
        let kind = if arm.is_some() { ArmKind::Spatial } else { ArmKind::Planar };
        for (name, v) in &file.parameters {
            let knob = Knob::parse_for(name, platform, kind).map_err(SpaceError::Knob)?;
            v.check(name)?;
            parameters.push((knob, *v));
        }
        parameters.sort_by_key(|(k, _)| *k);
        check_corners(builder, &base, &parameters, arm)?;
        if arm.is_none() {
            check_joints(builder, &base, &parameters, &initial)?;
        }
        // The drawn variables: distance and heading first, then the others in column order.
        let mut drawn: Vec<&str> = ["distance", "heading"]
            .into_iter()
            .chain(INITIAL)
            .filter(|n| {
                INITIAL.iter().position(|m| m == n).and_then(|i| initial[i]).is_some_and(Value::is_range)
            })
            .collect();
        drawn.extend(parameters.iter().filter(|(_, v)| v.is_range()).map(|(k, _)| k.name()));
        drawn.dedup();
        let map = match &file.map {
            Some(m) => m.clone(),
            None => {
                let Some(x) = drawn.first() else {
                    return Err(SpaceError::NothingDrawn);
                };
                MapSpec {
                    x: (*x).to_string(),
                    y: drawn.get(1).map(|y| (*y).to_string()),
                    bins: default_bins(),
                }
            }
        };
        for axis in std::iter::once(&map.x).chain(map.y.as_ref()) {
            if !drawn.contains(&axis.as_str()) {
                return Err(SpaceError::MapAxis(axis.clone()));
            }
        }
        if map.y.as_ref() == Some(&map.x) {
            return Err(SpaceError::SameAxes(map.x));
        }
        if map.bins.iter().any(|b| !(1..=100).contains(b)) {
            return Err(SpaceError::MapBins(map.bins));
        }
        let j = file.judge.unwrap_or_default();
        let d = Judge::default();
        let judge = Judge {
            tolerance: j.tolerance.unwrap_or(d.tolerance),
            // The default window, but never longer than the run.
            window: j.window.unwrap_or(d.window.min(base.duration)),
            divergence: j.divergence.unwrap_or(d.divergence),
            track_after: j.track_after,
        };
        if let Some(t) = judge.track_after {
            if !(t >= 0.0 && t < base.duration) {
                return Err(SpaceError::TrackAfter { duration: base.duration, value: t });
            }
        }
        if !(judge.tolerance.is_finite() && judge.tolerance > 0.0) {
            return Err(SpaceError::Tolerance(judge.tolerance));
        }
        if !(judge.window > 0.0 && judge.window <= base.duration) {
            return Err(SpaceError::Window { duration: base.duration, value: judge.window });
        }
        if !(judge.divergence.is_finite() && judge.divergence > judge.tolerance) {
            return Err(SpaceError::Divergence(judge.divergence));
        }
        Ok(Self { initial, parameters, map, judge })
    }

    /// The point at the uniform draws `u` (one per variable: [`INITIAL`] then `knobs::ALL`).
    pub fn point(&self, u: &[f64; DRAWS]) -> Point {
        let mut initial = [f64::NAN; 9];
        for (i, v) in self.initial.iter().enumerate() {
            if let Some(v) = v {
                initial[i] = v.at(u[i]);
            }
        }
        let parameters = self
            .parameters
            .iter()
            .map(|(k, v)| {
                let slot = INITIAL.len() + knobs::ALL.iter().position(|a| a == k).unwrap_or(0);
                (*k, v.at(u[slot]))
            })
            .collect();
        Point { initial, parameters }
    }

    /// The scenario of a point: `builder`'s with the point's start, `α(0)` and knobs.
    ///
    /// # Errors
    /// The point's scenario is invalid (the corner check makes this a bug).
    pub fn scenario(
        &self,
        builder: &ScenarioBuilder,
        base: &Scenario,
        p: &Point,
    ) -> Result<Scenario, ScenarioError> {
        let [d, b, h, q1, q2, q3, a1, a2, xi] = p.initial;
        let start = crate::domain::scenario::Start {
            target: [d * b.cos(), d * b.sin(), h],
            joints: [q1, q2, q3],
            steering: xi.is_finite().then_some(xi),
        };
        knobs::apply(builder, base, &p.parameters).start(start).initial_alpha([a1, a2]).build()
    }

    /// The spatial run of a point: `builder`'s scenario with the point's `α(0)` and platform
    /// knobs, `setup`'s arm scaled by its arm knobs, `setup`'s target.
    ///
    /// # Errors
    /// The point's scenario is invalid (the corner check makes this a bug).
    pub fn spatial_scenario(
        &self,
        builder: &ScenarioBuilder,
        base: &Scenario,
        setup: &SpatialSetup,
        p: &Point,
    ) -> Result<SpatialScenario, PointError> {
        let [.., a1, a2, _] = p.initial;
        spatial_at(builder, base, setup, &p.parameters, [a1, a2])
    }
}

/// Why the spatial run of a point cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum PointError {
    /// The planar scenario it is made from (the platform law's parameters).
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The spatial run: its arm, law, target or plant.
    #[error(transparent)]
    Spatial(#[from] SpatialRunError),
}

/// The spatial run of `builder` with the knobs `values` and `α(0)` = `alpha`.
fn spatial_at(
    builder: &ScenarioBuilder,
    base: &Scenario,
    setup: &SpatialSetup,
    values: &[(Knob, f64)],
    alpha: [f64; 2],
) -> Result<SpatialScenario, PointError> {
    let s = knobs::apply(builder, base, values).initial_alpha(alpha).build()?;
    setup.scenario(s, values).map_err(|e| PointError::Spatial(e.into()))
}

/// How many uniform draws a point takes: one per initial variable and one per knob, whether
/// drawn or not, so that adding a range to a space leaves the other variables' draws alone.
pub const DRAWS: usize = INITIAL.len() + knobs::ALL.len();

/// The scenario's own start in [`INITIAL`] order (`steering` NaN).
fn base_start(s: &Scenario) -> Result<[f64; 9], PlantSetupError> {
    let plant = crate::domain::plant_setup::build(s)?;
    let x = plant.truth();
    let r_bd = x.base.between(&x.target);
    let a = s.controller.initial_alpha;
    Ok([
        r_bd.x.hypot(r_bd.y),
        r_bd.y.atan2(r_bd.x),
        r_bd.theta,
        x.joints[0],
        x.joints[1],
        x.joints[2],
        a[0],
        a[1],
        f64::NAN,
    ])
}

/// Builds the scenario at every corner of the parameter box (at most 2¹⁶); with a spatial arm,
/// checks the spatial run there too (arm, law, the target's height against the arm's reach).
fn check_corners(
    builder: &ScenarioBuilder,
    base: &Scenario,
    parameters: &[(Knob, Value)],
    arm: Option<&SpatialSetup>,
) -> Result<(), SpaceError> {
    let ranged: Vec<usize> = (0..parameters.len()).filter(|&i| parameters[i].1.is_range()).collect();
    for corner in 0u32..(1 << ranged.len()) {
        let values: Vec<(Knob, f64)> = parameters
            .iter()
            .enumerate()
            .map(|(i, (k, v))| {
                let (lo, hi) = v.bounds();
                let high = ranged.iter().position(|&r| r == i).is_some_and(|bit| corner & (1 << bit) != 0);
                (*k, if high { hi } else { lo })
            })
            .collect();
        let at = || values.iter().map(|(k, v)| format!("{} = {v}", k.name())).collect::<Vec<_>>().join(", ");
        if let Err(why) = knobs::apply(builder, base, &values).build() {
            return Err(SpaceError::Corner { at: at(), why });
        }
        if let Some(setup) = arm {
            let alpha = base.controller.initial_alpha;
            let checked = spatial_at(builder, base, setup, &values, alpha)
                .and_then(|s| spatial::check(&s).map_err(PointError::from));
            if let Err(why) = checked {
                return Err(SpaceError::SpatialCorner { at: at(), why: Box::new(why) });
            }
        }
    }
    Ok(())
}

/// The joints' ranges must lie strictly inside the limits at every stroke of the space.
fn check_joints(
    builder: &ScenarioBuilder,
    base: &Scenario,
    parameters: &[(Knob, Value)],
    initial: &[Option<Value>; 9],
) -> Result<(), SpaceError> {
    // The narrowest limits: the shortest stroke, if it is drawn.
    let shortest: Vec<(Knob, f64)> =
        parameters.iter().filter(|(k, _)| *k == Knob::Stroke).map(|(k, v)| (*k, v.bounds().0)).collect();
    let s = knobs::apply(builder, base, &shortest).build().map_err(SpaceError::Stroke)?;
    let lim = s.controller.params::<f64>().joint_limits;
    for j in 0..3 {
        let Some(v) = initial[3 + j] else { continue };
        let (lo, hi) = v.bounds();
        if lo <= lim.lower[j] || hi >= lim.upper[j] {
            return Err(SpaceError::JointRange {
                joint: j + 1,
                value: v,
                lower: lim.lower[j],
                upper: lim.upper[j],
            });
        }
    }
    Ok(())
}
