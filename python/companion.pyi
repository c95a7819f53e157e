"""companion: the companion controller for mobile manipulators (the law and the simulator) from Python.

Units are SI throughout: metres, radians, seconds (velocities in m/s and rad/s).

A measurement row (``Measurement.row``, one row of ``LawBatch.step``'s array):

- planar (the RPR arm, 14 numbers): ``t, x_b, y_b, θ_b, ξ, q1, q2, q3, x_d, y_d, θ_d, u_d1, u_d2, u_d3``;
- spatial (N = 6..8 joints, 23 + N numbers): ``t, x_b, y_b, θ_b, ξ, q1..qN, R_d (9, row-major),
  p_d (3), v_d (3), ω_d (3)``.

A command is ``[v, v_lat, ω, v_ξ, u_q1, …]`` (4 + joints); diagnostics are
``[‖e_p‖, h_s, Ψ, saturation, α̇1, α̇2, joint_scale]`` (7).
"""

from os import PathLike
from typing import Any, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

Platform = Literal["unicycle", "car", "omni"]
Choice = Literal["a", "b", "c", "d"]
ScalarType = Literal["f64", "f32"]
Discretisation = Literal["midpoint", "sampled"]
# `limits`: a named set merged with the config file's limits, the stricter value winning per key
# ("none": no limit at all, the file's dropped); scenario.json records each limit's source.
Limits = Literal["none", "realistic", "tiago"]
Path = Union[str, PathLike]
FloatArray = npt.NDArray[np.float64]
ArrayLike = Union[Sequence[float], FloatArray]

STEP_ERRORS: list[str]
"""The StepError variants, in the order of LawBatch.step's error codes (code i + 1 is STEP_ERRORS[i])."""

class Measurement:
    """What the law reads at one step."""

    def __init__(
        self,
        t: float,
        base: ArrayLike,
        joints: ArrayLike,
        target: Union[ArrayLike, Sequence[Sequence[float]]],
        target_velocity: ArrayLike,
        steering: float = 0.0,
    ) -> None:
        """t: time (s); base: (x, y, θ) (m, m, rad); joints: q (rad or m; 3 planar, 6–8 spatial);
        target: planar (x, y, θ) or a 4×4 homogeneous transform (m; z up, the platform's plane at z = 0);
        target_velocity: planar body velocity (v_x, v_y, ω) (m/s, m/s, rad/s) or spatial (v, ω) (6);
        steering: the car's ξ = tan φ / ℓ (1/m), ignored by the other platforms."""
    @property
    def row(self) -> FloatArray:
        """The flat row a Law steps on."""
    @property
    def t(self) -> float:
        """Time (s)."""
    @property
    def joints(self) -> int: ...
    @property
    def spatial(self) -> bool: ...

class Output:
    """One step's result: the command to hold over the period and the diagnostics the CLI logs."""

    @property
    def v(self) -> float:
        """Forward speed (m/s)."""
    @property
    def v_lat(self) -> float:
        """Lateral speed (m/s; omnidirectional platform, else 0)."""
    @property
    def omega(self) -> float:
        """Turn rate (rad/s)."""
    @property
    def v_xi(self) -> float:
        """Steering rate (1/(m·s); car-like platform, else 0)."""
    @property
    def joint_rates(self) -> FloatArray:
        """u_q (rad/s or m/s), one per joint."""
    @property
    def command(self) -> FloatArray:
        """[v, v_lat, ω, v_ξ, u_q…]."""
    @property
    def ep_norm(self) -> float:
        """‖e_p‖ as the law estimates it (m and rad mixed; NaN when rejected)."""
    @property
    def h_s(self) -> float:
        """The secondary task function h_s."""
    @property
    def psi(self) -> float:
        """The weight Ψ, eqs. (52)–(53)."""
    @property
    def saturation(self) -> float:
        """The common saturation factor (≥ 1)."""
    @property
    def alpha_rate(self) -> Tuple[float, float]:
        """α̇ (rad/s)."""
    @property
    def joint_scale(self) -> float:
        """The joint guard's factor (≥ 1)."""
    @property
    def diagnostics(self) -> FloatArray:
        """[‖e_p‖, h_s, Ψ, saturation, α̇1, α̇2, joint_scale]."""
    @property
    def error(self) -> Optional[str]:
        """The StepError variant if the step was rejected (then the command is zero)."""

class Arm:
    """A spatial arm (6 to 8 joints): a preset (``'ur5'``, ``'panda'``), a TOML arm file, or the
    chain between two links of a URDF. ``Law(arm=…)`` and ``simulate(arm=…)`` take one."""

    def __init__(self, arm: Union[Literal["ur5", "panda"], Path]) -> None: ...
    @staticmethod
    def from_urdf(
        path: Path,
        base_link: Optional[str] = None,
        tip_link: Optional[str] = None,
        srdf: Optional[Path] = None,
        home_state: Optional[str] = None,
        home: Optional[Union[Sequence[float], dict[str, float]]] = None,
    ) -> "Arm":
        """The chain from ``base_link`` (the URDF's root link if None) to ``tip_link`` (required),
        fixed joints folded, continuous joints without limits; its home from the SRDF's
        ``<group_state name=home_state>`` and/or ``home`` (every joint's value in the chain's
        order, or a dict of joints by name over the state's), strictly inside the limits.
        Raises ``ConfigError`` or ``ScenarioError`` naming the file and the joint or link."""
    @property
    def name(self) -> str:
        """The arm's name (a URDF's ``<robot name>``)."""
    @property
    def joints(self) -> int:
        """The number of joints."""
    @property
    def joint_names(self) -> list[str]:
        """The joints' names, from the base outwards."""
    @property
    def lower(self) -> FloatArray:
        """Lower limits (rad or m; -inf for a continuous joint)."""
    @property
    def upper(self) -> FloatArray:
        """Upper limits (rad or m; inf for a continuous joint)."""
    @property
    def max_velocity(self) -> FloatArray:
        """Speed limits (rad/s or m/s; inf where none)."""
    @property
    def home(self) -> FloatArray:
        """The home configuration (rad or m)."""
    def forward(self, q: ArrayLike) -> FloatArray:
        """The tip's pose in the base link's frame at ``q`` (4×4 homogeneous matrix, m)."""
    def jacobian(self, q: ArrayLike) -> FloatArray:
        """The geometric Jacobian at ``q`` (6×N): rows (v; ω) of the tip's origin in the base
        link's axes (Pinocchio's LOCAL_WORLD_ALIGNED with the base link as the world)."""

class Law:
    """One controller: the planar RPR arm or a spatial arm on a platform, in f64 or f32, built
    from companion sim's presets and --config TOML."""

    def __init__(
        self,
        platform: Platform = "unicycle",
        choice: Choice = "a",
        arm: Union[Literal["rpr", "ur5", "panda"], Path, "Arm", None] = None,
        scalar: ScalarType = "f64",
        *,
        config: Optional[Path] = None,
        discretisation: Optional[Discretisation] = None,
        psi_rate_in_drift: bool = False,
        explicit_rest_filter: bool = False,
        limits: Optional[Limits] = None,
    ) -> None:
        """Raises a ParamError subclass (invalid parameter), ConfigError (bad file) or ScenarioError."""
    @property
    def joints(self) -> int: ...
    @property
    def spatial(self) -> bool: ...
    @property
    def measurement_width(self) -> int:
        """Numbers in a measurement row: 14 planar, 23 + joints spatial."""
    def step(self, measurement: Union[Measurement, ArrayLike], period: float, delay: float = 0.0) -> Output:
        """The command to hold for `period` s, taking effect `delay` s after the measurement.
        Raises the StepError subclass of a rejection (its .command is the zero command); the
        law's state is then unchanged."""
    def time_rust_steps(self, measurements: FloatArray, period: float, delay: float = 0.0) -> FloatArray:
        """Benchmark: each Rust step's time (ns) over the rows of `measurements`, no Python between."""

class LawBatch:
    """n independent laws of one configuration, stepped in one call."""

    def __init__(
        self,
        n: int,
        platform: Platform = "unicycle",
        choice: Choice = "a",
        arm: Union[Literal["rpr", "ur5", "panda"], Path, "Arm", None] = None,
        scalar: ScalarType = "f64",
        *,
        config: Optional[Path] = None,
        discretisation: Optional[Discretisation] = None,
        psi_rate_in_drift: bool = False,
        explicit_rest_filter: bool = False,
        limits: Optional[Limits] = None,
    ) -> None: ...
    def __len__(self) -> int: ...
    @property
    def joints(self) -> int: ...
    @property
    def measurement_width(self) -> int: ...
    def step(
        self, measurements: FloatArray, period: float, delay: float = 0.0
    ) -> Tuple[FloatArray, FloatArray, npt.NDArray[np.uint8]]:
        """Law i steps on row i of `measurements` (n, measurement_width). Returns (commands (n, 4 + joints),
        diagnostics (n, 7), errors (n,) uint8: 0 accepted, else 1 + index in STEP_ERRORS)."""

class Plant:
    """companion sim's planar plant (RK4 at a fixed step), for a loop written in Python."""

    def __init__(
        self,
        trajectory: Literal[1, 2] = 1,
        choice: Choice = "a",
        platform: Platform = "unicycle",
        *,
        config: Optional[Path] = None,
        target_file: Optional[Path] = None,
        actuator_lag: Optional[float] = None,
        noise: bool = False,
        wheel_scale_error: Optional[float] = None,
        seed: int = 1,
    ) -> None: ...
    def measure(self) -> Measurement:
        """What the controller measures now (with noise, if any)."""
    def truth(self) -> Measurement:
        """The true state."""
    def advance(self, command: FloatArray, dt: float) -> None:
        """One step of dt s with command [v, v_lat, ω, v_ξ, u_q1, u_q2, u_q3] held."""
    @property
    def t(self) -> float:
        """Time (s)."""
    @property
    def ep_norm(self) -> float:
        """The true ‖e_p‖, eq. (42)."""

def simulate(
    trajectory: Literal[1, 2] = 1,
    choice: Choice = "a",
    platform: Platform = "unicycle",
    arm: Union[Literal["rpr", "ur5", "panda"], Path, "Arm", None] = None,
    *,
    dt: float = 0.001,
    duration: Optional[float] = None,
    scalar: ScalarType = "f64",
    config: Optional[Path] = None,
    target_file: Optional[Path] = None,
    psi_rate_in_drift: bool = False,
    explicit_rest_filter: bool = False,
    discretisation: Optional[Discretisation] = None,
    limits: Optional[Limits] = None,
    actuator_lag: Optional[float] = None,
    noise: bool = False,
    wheel_scale_error: Optional[float] = None,
    seed: int = 1,
    log_every: int = 10,
    delay: float = 0.0,
    delay_compensation: bool = True,
    max_rejected: float = 0.01,
    out: Optional[Path] = None,
) -> Tuple[dict[str, Any], dict[str, Any]]:
    """companion sim with these flags (duration default 120 s): (timeseries, summary). timeseries: the
    logged rows as numpy arrays (t, base, steering, joints, end_effector, target, ep_norm, command,
    h_s, psi, saturation, alpha_rate, joint_scale, status; spatial: poses as (n, 4, 4)); summary:
    summary.json as a dict, its trajectory_digest the CLI's. Files go to `out`, else a removed temp folder."""

class CompanionError(Exception): ...
class StepError(CompanionError):
    command: FloatArray
    output: Output
    variant: str
    field: Optional[str]
    joint: Optional[int]

class ParamError(CompanionError):
    param: str
    joint: Optional[int]
    rule: str

class ScenarioError(CompanionError): ...
class ConfigError(ScenarioError): ...
class NonFinite(StepError): ...
class BadTimeStep(StepError): ...
class JointAtLimit(StepError): ...
class SingularArm(StepError): ...
class SingularTaskJacobian(StepError): ...
class TargetYawUndefined(StepError): ...
class BadDelay(StepError): ...
class NumericalFailure(StepError): ...
class NonFiniteParameter(ParamError): ...
class NotPositive(ParamError): ...
class Negative(ParamError): ...
class NotInUnitInterval(ParamError): ...
class EmptyInterval(ParamError): ...
class PenaltyMarginTooWide(ParamError): ...
class WeightMarginOrder(ParamError): ...
class Transversality(ParamError): ...
class Decomposition51NeedsPsiOne(ParamError): ...
class Geometry(ParamError): ...
class TooLarge(ParamError): ...
class NotOrthonormal(ParamError): ...
class NotUnitVector(ParamError): ...
class TooFewJoints(ParamError): ...
class HomeOutsideLimits(ParamError): ...
class NotPlanar(ParamError): ...
class PeriodTooLong(ParamError): ...
