//! The platform laws' parameters as a config file writes them: the `[unicycle]` (Lemma 1)
//! and `[car]` (Lemma 2 and the steering gain of (59)) tables.
//!
//! A leaf of the domain layer: [`crate::domain::controller`] builds the core's `Unicycle` and
//! `CarLike` from them, [`crate::domain::scenario`] reads them from `--config`, and [`crate::domain::arm`]
//! from an arm file that carries the settings its joints need — none of the three through
//! another.

use serde::{Deserialize, Serialize};

/// Lemma 1's parameters (`companion-core`'s `Unicycle`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnicycleConfig {
    /// `ε₁` (m).
    pub epsilon_1: f64,
    /// `ε₂`.
    pub epsilon_2: f64,
}

impl Default for UnicycleConfig {
    fn default() -> Self {
        Self { epsilon_1: 0.2, epsilon_2: 0.4 }
    }
}

/// Lemma 2's parameters and the steering gain of (59) (`companion-core`'s `CarLike`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CarConfig {
    /// `ε`.
    pub epsilon: f64,
    /// `η₁`, with `6 η₂ η₃ > 8 η₃ + η₁ η₂`.
    pub eta_1: f64,
    /// `η₂`.
    pub eta_2: f64,
    /// `η₃`.
    pub eta_3: f64,
    /// `k` (1/s).
    pub k: f64,
}

impl Default for CarConfig {
    /// The car-like defaults, found by `companion tune` (docs/book/src/law.md, "The car-like platform"):
    /// on trajectory 1 runs (a) and (c) and trajectory 2 run (c), with the paper's RPR arm and
    /// the realistic velocity limits,
    ///
    /// ```text
    /// companion tune --platform car --limits realistic --runs 1a,1c,2c \
    ///     --space docs/tune/car-space.toml --budget 300 --out out/tune-car
    /// ```
    ///
    /// rounded to three digits. `ε(1 + η₂) = 0.44 m`: the platform's excursions from its
    /// companion frame fit the prismatic joint's stroke (0.7 m), where the earlier ε = 0.3,
    /// η₂ = 3 gave ±1.2 m; the large `η₃` and `η₁` keep the heading and steering oscillations
    /// (`~ε²η₃`, `εη₁`) large enough to manoeuvre. Lemma 2: `6η₂η₃ = 176 > 8η₃ + η₁η₂ = 165`.
    fn default() -> Self {
        Self { epsilon: 0.152, eta_1: 21.9, eta_2: 1.9, eta_3: 15.4, k: 26.6 }
    }
}
