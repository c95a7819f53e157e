"""The Python package against the `companion` CLI: expected values come from the CLI's own
runs (its summary.json digests, the repository's golden digests), never from the package."""

import json
import math
import pathlib
import struct
import subprocess

import numpy as np
import pytest

import companion

# Not `from conftest import ROOT`: pytest runs this file beside bridges/*/tests, whose conftest
# modules share the name, and the first one imported wins.
ROOT = pathlib.Path(__file__).resolve().parents[2]

# FNV-1a 64 over the IEEE-754 bits, as runtime/src/domain/record/digest.rs defines the trajectory digest.
OFFSET, PRIME, MASK = 0xCBF29CE484222325, 0x100000001B3, (1 << 64) - 1


def fnv(h, x):
    for b in struct.pack("<d", x):
        h = ((h ^ b) * PRIME) & MASK
    return h


def cli_digest(cli, tmp_path, *args):
    out = tmp_path / "run"
    subprocess.run([cli, "sim", *args, "--no-plots", "--log-every", "1000", "--out", out], check=True, capture_output=True)
    return json.loads((out / "summary.json").read_text())["trajectory_digest"]


def test_a_python_stepped_run_equals_companion_sim_bit_for_bit(cli, tmp_path):
    """Run (a), f64, 5 s: the law stepped from a Python loop on the simulator's plant gives the
    trajectory digest of `companion sim` (every state and command of every step, to the bit)."""
    want = cli_digest(cli, tmp_path, "--trajectory", "1", "--choice", "a", "--duration", "5")
    law, plant, dt = companion.Law("unicycle", "a"), companion.Plant(1, "a", "unicycle"), 0.001
    h = OFFSET
    for n in range(5001):
        m = plant.measure()
        out = law.step(m, dt, 0.0)
        row = m.row
        for x in row[:8]:  # t, x_b, y_b, θ_b, ξ, q₁, q₂, q₃
            h = fnv(h, x)
        for x in out.command:  # v, v_lat, ω, v_ξ, u_q
            h = fnv(h, x)
        if n < 5000:
            plant.advance(out.command, dt)
    assert f"{h:016x}" == want


def golden():
    rows = {}
    for line in (ROOT / "runtime" / "tests" / "golden" / "digests.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, digest, *args = line.split()
            rows[name] = (digest, args)
    return rows


PAPER_RUNS = [f"uni-{t}{c}" for t in "12" for c in "abcd"]


@pytest.mark.parametrize("name", PAPER_RUNS + ["car-1c", "omni-2a", "uni-1a-f32"])
def test_simulate_reproduces_the_golden_digest(name):
    """The paper's 8 runs (and the car, omni and f32 references): simulate() gives the digest the
    repository stores for `companion sim` with the same flags (runtime/tests/golden.rs)."""
    digest, args = golden()[name]
    flags = dict(zip(args[::2], args[1::2]))
    _, summary = companion.simulate(
        int(flags["--trajectory"]),
        flags["--choice"],
        flags.get("--platform", "unicycle"),
        scalar=flags.get("--scalar", "f64"),
        log_every=1000,
    )
    assert summary["trajectory_digest"] == digest


def test_simulate_timeseries_match_the_cli_csv(cli, tmp_path):
    """The logged rows are those of the CLI's timeseries.csv (the CSV writes shortest round-trip decimals)."""
    out = tmp_path / "csv"
    subprocess.run([cli, "sim", "--duration", "2", "--no-plots", "--out", out], check=True, capture_output=True)
    csv = np.genfromtxt(out / "timeseries.csv", delimiter=",", names=True, dtype=None, encoding=None)
    ts, summary = companion.simulate(1, "a", duration=2.0)
    assert np.array_equal(ts["t"], csv["t"])
    assert np.array_equal(ts["base"][:, 0], csv["x_b"])
    assert np.array_equal(ts["joints"][:, 1], csv["q2"])
    assert np.array_equal(ts["command"][:, 2], csv["omega"])
    assert summary["steps"] == 2001


def planar(q=(0.1, 0.5, 0.1), base=(0.0, 0.0, 0.0), target=(1.0, 0.5, 0.2), u=(0.1, 0.0, 0.05), t=0.0):
    return companion.Measurement(t, base, q, target, u)


@pytest.mark.parametrize(
    "measurement, period, delay, error",
    [
        (planar(base=(0.0, 0.0, math.nan)), 0.001, 0.0, companion.NonFinite),
        (planar(), -0.001, 0.0, companion.BadTimeStep),
        (planar(), math.inf, 0.0, companion.BadTimeStep),
        (planar(q=(0.1, 0.8, 0.1)), 0.001, 0.0, companion.JointAtLimit),
        (planar(), 0.001, -1.0, companion.BadDelay),
        (planar(target=(1e300, 1e300, 0.2)), 0.001, 0.0, companion.NumericalFailure),
    ],
)
def test_a_bad_measurement_raises_its_step_error_with_the_zero_command(measurement, period, delay, error):
    law = companion.Law()
    with pytest.raises(error) as e:
        law.step(measurement, period, delay)
    assert isinstance(e.value, companion.StepError) and isinstance(e.value, companion.CompanionError)
    assert e.value.variant == error.__name__
    assert np.array_equal(e.value.command, np.zeros(7))
    assert e.value.output.error == error.__name__
    # The law's state is as before: a good step afterwards is accepted.
    assert law.step(planar(), 0.001).error is None


def test_non_finite_and_joint_at_limit_say_which():
    with pytest.raises(companion.NonFinite) as e:
        companion.Law().step(planar(u=(math.nan, 0.0, 0.0)), 0.001)
    assert e.value.field == "target_velocity"
    with pytest.raises(companion.JointAtLimit) as e:
        companion.Law().step(planar(q=(0.1, 0.8, 0.1)), 0.001)
    assert e.value.joint == 1


def test_a_vertical_target_axis_raises_target_yaw_undefined():
    ts, _ = companion.simulate(1, "a", arm="ur5", duration=0.01)
    target = ts["target"][0].copy()
    target[:3, :3] = [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]  # x axis along z
    m = companion.Measurement(0.0, ts["base"][0], ts["joints"][0], target, np.zeros(6))
    with pytest.raises(companion.TargetYawUndefined) as e:
        companion.Law(arm="ur5").step(m, 0.001)
    assert np.array_equal(e.value.command, np.zeros(10))


def test_every_step_error_variant_has_its_class():
    # SingularArm and SingularTaskJacobian have no measurement of the presets that reaches them
    # within the joint limits (core's unit tests raise them on purpose-built arms).
    for name in companion.STEP_ERRORS:
        assert issubclass(getattr(companion, name), companion.StepError)


@pytest.mark.parametrize(
    "toml, error, param",
    [
        ("[controller]\ngain = [nan, 1, 1]", companion.NonFiniteParameter, "gain"),
        ("[controller]\ngain = [0, 1, 1]", companion.NotPositive, "gain"),
        ("[controller]\njoint_step_fraction = 2.0", companion.NotInUnitInterval, "joint_step_fraction"),
        ("[controller]\ngain = [1e7, 1, 1]", companion.TooLarge, "gain"),
        ("[controller]\nmax_time_step = 0.5", companion.PeriodTooLong, "max_time_step"),
        ("[controller]\nregularisation_gain = -1", companion.Negative, "regularisation_gain"),
        ("[controller]\npenalty_margin = [1, 1, 1]", companion.PenaltyMarginTooWide, "penalty_margin"),
        ("[unicycle]\nepsilon_1 = 100\nepsilon_2 = 0.4", companion.TooLarge, "epsilon_1"),
        ("[arm]\nstroke = -1", companion.NotPositive, "arm.stroke"),
        ("[car]\nepsilon = 0.3\neta_1 = 1\neta_2 = 1\neta_3 = 1\nk = 5", companion.Transversality, "eta"),
    ],
)
def test_a_bad_config_raises_its_param_error(tmp_path, toml, error, param):
    path = tmp_path / "c.toml"
    path.write_text(toml)
    with pytest.raises(error) as e:
        companion.Law("car" if "[car]" in toml else "unicycle", config=str(path))
    assert isinstance(e.value, companion.ParamError)
    assert e.value.param.endswith(param) and e.value.rule == ("NonFinite" if error is companion.NonFiniteParameter else error.__name__)


def test_a_bad_arm_file_raises_the_param_error_of_its_rule(tmp_path):
    text = (ROOT / "examples" / "arms" / "ur5.toml").read_text()
    path = tmp_path / "arm.toml"
    path.write_text(text.replace("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 2.0]", 1))
    with pytest.raises(companion.NotUnitVector) as e:
        companion.Law(arm=str(path))
    assert e.value.param == "joint 1: axis" and isinstance(e.value, companion.ParamError)


def test_a_bad_file_or_scenario_raises_config_or_scenario_error(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[controller]\nG_gain = [1, 2, 3]")
    with pytest.raises(companion.ConfigError):
        companion.Law(config=str(path))
    with pytest.raises(companion.ConfigError):
        companion.Law(arm=str(tmp_path / "missing.toml"))
    with pytest.raises(companion.ScenarioError):
        companion.simulate(dt=-1.0)


def test_the_batch_call_equals_single_steps():
    rng = np.random.default_rng(7)
    n = 16
    for kw in [dict(platform="unicycle"), dict(platform="car", scalar="f32"), dict(platform="omni", choice="c"), dict(arm="ur5")]:
        batch = companion.LawBatch(n, **kw)
        singles = [companion.Law(**kw) for _ in range(n)]
        base = companion.simulate(1, kw.get("choice", "a"), kw.get("platform", "unicycle"), arm=kw.get("arm", "rpr"), duration=0.01)[0]
        if kw.get("arm") == "ur5":
            row = np.concatenate([[0.0], base["base"][0], [0.0], base["joints"][0], base["target"][0][:3, :3].ravel(), base["target"][0][:3, 3], np.zeros(6)])
        else:
            row = np.concatenate([[0.0], base["base"][0], [0.0], base["joints"][0], base["target"][0], [0.1, 0.0, 0.05]])
        for k in range(20):
            rows = np.tile(row, (n, 1))
            rows[:, 0] = k * 0.001
            rows[:, 1:3] += rng.normal(0.0, 0.05, size=(n, 2))
            rows[3, 1] = math.nan  # one law rejects its measurement
            cmd, diag, err = batch.step(rows, 0.001)
            for i, law in enumerate(singles):
                try:
                    out = law.step(rows[i], 0.001)
                    assert err[i] == 0
                    np.testing.assert_array_equal(cmd[i], out.command)
                    np.testing.assert_array_equal(diag[i], out.diagnostics)
                except companion.StepError as e:
                    assert companion.STEP_ERRORS[err[i] - 1] == type(e).__name__
                    np.testing.assert_array_equal(cmd[i], e.command)


def test_every_platform_arm_and_scalar_builds_and_steps(tmp_path):
    arm_file = ROOT / "examples" / "arms" / "ur5.toml"
    for platform in ["unicycle", "car", "omni"]:
        for scalar in ["f64", "f32"]:
            assert companion.Law(platform, "a", "rpr", scalar).step(planar(), 0.001).error is None
            for arm in ["ur5", "panda", str(arm_file)]:
                law = companion.Law(platform, "a", arm, scalar)
                assert law.spatial and law.joints in (6, 7)


def test_a_spatial_simulate_gives_the_cli_digest(cli, tmp_path):
    """simulate(arm="ur5") is `companion sim --arm ur5` (its summary.json digest), here on the car."""
    want = cli_digest(cli, tmp_path, "--arm", "ur5", "--platform", "car", "--duration", "3")
    ts, summary = companion.simulate(1, "a", "car", arm="ur5", duration=3.0)
    assert summary["trajectory_digest"] == want
    assert ts["target"].shape[1:] == (4, 4) and ts["command"].shape[1] == 10


def test_a_measurement_row_as_array_or_list_is_the_measurement():
    m = planar()
    a, b, c = companion.Law(), companion.Law(), companion.Law()
    for k in range(5):
        oa, ob, oc = a.step(m, 0.001), b.step(m.row, 0.001), c.step(list(m.row), 0.001)
        np.testing.assert_array_equal(oa.command, ob.command)
        np.testing.assert_array_equal(oa.command, oc.command)
    with pytest.raises(ValueError):
        a.step(m.row[:-1], 0.001)


def test_the_panda_simulate_carries_its_platform_settings_as_the_cli(cli, tmp_path):
    """`companion sim --arm panda` runs the unicycle with the arm's own Lemma 1 settings; simulate too."""
    want = cli_digest(cli, tmp_path, "--arm", "panda", "--duration", "2")
    _, summary = companion.simulate(1, "a", arm="panda", duration=2.0)
    assert summary["trajectory_digest"] == want


def test_limits_compose_with_the_config_file_as_the_cli(cli, tmp_path):
    """`limits='tiago'` merges with the config file's limits, the stricter value per key: the
    file's `alpha_rate` caps the commanded phase rate (its timeseries column), the TIAGo's
    2.09 rad/s caps ω, scenario.json names each source, and the run is the CLI's bit for bit."""
    cfg = tmp_path / "limits.toml"
    cfg.write_text("[velocity_limits]\nalpha_rate = 0.8\nangular = 3.0\n")
    out = tmp_path / "py"
    ts, s = companion.simulate(1, "a", duration=5.0, config=str(cfg), limits="tiago", log_every=1, out=str(out))
    assert np.abs(ts["alpha_rate"][:, 0]).max() <= 0.8 * (1 + 1e-12)
    assert np.abs(ts["command"][:, 2]).max() <= 2.09 * (1 + 1e-12)
    applied = {a["key"]: (a["value"], a["from"]) for a in json.loads((out / "scenario.json").read_text())["limits"]["applied"]}
    assert applied["velocity_limits.alpha_rate"] == (0.8, "config file")
    assert applied["velocity_limits.angular"] == (2.09, "limits tiago")
    assert applied["acceleration_limits.forward"] == (1.0, "limits tiago")
    assert s["trajectory_digest"] == cli_digest(cli, tmp_path, "--duration", "5", "--config", cfg, "--limits", "tiago")
