"""Robots from their URDFs (`companion.Arm.from_urdf`), held to Pinocchio.

Pinocchio (PyPI `pin`) and the URDFs of PyPI `example-robot-data` are written by nobody here;
scripts/setup installs both into target/py. For every serial chain of 6 to 8 moving joints
the package's robots have (from a URDF's root link to a leaf link, none of them a mimic
joint), companion's forward kinematics and Jacobian at 1 000 random configurations inside the
limits equal Pinocchio's to 1e-12 (m, rad; f64). Pinocchio's frame: the tip link's BODY frame
in the root link's (`oMf`); its Jacobian LOCAL_WORLD_ALIGNED — both with the base link as the
world, which is what `Arm.forward` and `Arm.jacobian` promise.
"""

import json
import math
import pathlib
import re
import sysconfig

import numpy as np
import pinocchio as pin
import pytest

import companion

ROBOTS = pathlib.Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
TOLERANCE = 1e-12
CONFIGURATIONS = 1000


def robot(rel):
    p = ROBOTS / rel
    assert p.exists(), f"{p}: scripts/setup installs example-robot-data into target/py"
    return p


def pin_model(path):
    return pin.buildModelFromUrdf(str(path))


def chains(path):
    """(root link, leaf link, joint names) of every chain of 6-8 moving joints in a URDF."""
    model = pin_model(path)
    root = model.frames[1].name if len(model.frames) > 1 else None
    # The root link is the BODY frame attached to the universe with no joint of its own.
    roots = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == 0]
    if not roots:
        return []
    root = roots[0]
    children = {model.frames[i].parentFrame for i in range(len(model.frames))}
    out = []
    for i, f in enumerate(model.frames):
        if f.type != pin.FrameType.BODY or i in children:
            continue
        joints = []
        j = f.parentJoint
        while j > 0:
            joints.append(model.names[j])
            j = model.parents[j]
        joints.reverse()
        if 6 <= len(joints) <= 8:
            out.append((root, f.name, joints))
    return out


def mimic_on_path(path, tip):
    """Whether a mimic joint lies between the root and `tip` in the URDF's own tree
    (Pinocchio folds mimic joints away, so its path does not show them)."""
    import xml.etree.ElementTree as ET

    joints = ET.fromstring(path.read_text()).findall("joint")
    parent = {j.find("child").get("link"): j for j in joints}
    link = tip
    while link in parent:
        j = parent[link]
        if j.find("mimic") is not None:
            return True
        link = j.find("parent").get("link")
    return False


def all_chains():
    found = []
    for path in sorted(ROBOTS.rglob("*.urdf")):
        try:
            cs = chains(path)
        except Exception:  # a file Pinocchio cannot load is not a reference
            continue
        for root, tip, joints in cs:
            if not mimic_on_path(path, tip):
                found.append((path.relative_to(ROBOTS).as_posix(), root, tip, tuple(joints)))
    return found


CHAINS = all_chains()
NAMED = [
    ("ur_description/urdf/ur5_robot.urdf", "base_link", "tool0"),
    ("panda_description/urdf/panda.urdf", "panda_link0", "panda_hand"),
    ("tiago_description/robots/tiago_no_hand.urdf", "base_footprint", "arm_tool_link"),
]


def mid_home(arm_limits):
    lower, upper = arm_limits
    return [0.0 if not math.isfinite(lo) else 0.5 * (lo + hi) for lo, hi in zip(lower, upper)]


def limits_from_urdf(path, joints):
    import xml.etree.ElementTree as ET

    by_name = {j.get("name"): j for j in ET.fromstring(path.read_text()).findall("joint")}
    lo, hi = [], []
    for n in joints:
        j = by_name[n]
        if j.get("type") == "continuous":
            lo.append(-math.inf)
            hi.append(math.inf)
        else:
            lim = j.find("limit")
            lo.append(float(lim.get("lower", 0)))
            hi.append(float(lim.get("upper", 0)))
    return lo, hi


def pin_joints(model, base, tip):
    """The moving joints from `base` down to `tip`, by Pinocchio's tree."""
    stop = model.frames[model.getFrameId(base, pin.FrameType.BODY)].parentJoint
    j = model.frames[model.getFrameId(tip, pin.FrameType.BODY)].parentJoint
    out = []
    while j != stop:
        out.append(model.names[j])
        j = model.parents[j]
    return out[::-1]


def compare(rel, base, tip, seed):
    path = robot(rel)
    model = pin_model(path)
    data = model.createData()
    names = pin_joints(model, base, tip)
    home = mid_home(limits_from_urdf(path, names))
    arm = companion.Arm.from_urdf(path, base, tip, home=home)
    assert arm.joint_names == names
    frame = model.getFrameId(tip, pin.FrameType.BODY)
    base_frame = model.getFrameId(base, pin.FrameType.BODY)
    ids = [model.getJointId(n) for n in arm.joint_names]
    rng = np.random.default_rng(seed)
    lower, upper = arm.lower, arm.upper
    worst_fk = worst_j = 0.0
    for _ in range(CONFIGURATIONS):
        qc = np.array(
            [rng.uniform(-math.pi, math.pi) if not math.isfinite(lo) else rng.uniform(lo, hi) for lo, hi in zip(lower, upper)]
        )
        q = pin.neutral(model)
        for jid, x in zip(ids, qc):
            jm = model.joints[jid]
            if jm.nq == 2:  # a continuous joint: (cos, sin)
                q[jm.idx_q], q[jm.idx_q + 1] = math.cos(x), math.sin(x)
            else:
                q[jm.idx_q] = x
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        ref = data.oMf[base_frame].inverse() * data.oMf[frame]
        jac = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        # In the base link's axes (the identity for a chain from the root link).
        rb = data.oMf[base_frame].rotation.T
        jref = np.vstack([rb @ jac[:3], rb @ jac[3:]])[:, [model.joints[j].idx_v for j in ids]]
        fk = arm.forward(qc)
        worst_fk = max(worst_fk, np.abs(fk[:3, :3] - ref.rotation).max(), np.abs(fk[:3, 3] - ref.translation).max())
        worst_j = max(worst_j, np.abs(arm.jacobian(qc) - jref).max())
    return worst_fk, worst_j


def test_every_serial_chain_of_6_to_8_joints_is_found():
    """The discovery finds the issue's robots (and more): a guard against an empty sweep."""
    names = {(rel, tip) for rel, _, tip, _ in CHAINS}
    for rel, _, tip in NAMED[:2]:
        assert (rel, tip) in names or any(r == rel for r, _ in names), rel
    assert len(CHAINS) >= 20, len(CHAINS)
    print(f"{len(CHAINS)} chains of 6-8 joints in {len({c[0] for c in CHAINS})} URDFs")


@pytest.mark.parametrize("rel,base,tip", NAMED)
def test_the_issues_robots_equal_pinocchio(rel, base, tip):
    fk, jac = compare(rel, base, tip, seed=1)
    print(f"{rel} {base}->{tip}: forward {fk:.2e}, jacobian {jac:.2e}")
    assert fk <= TOLERANCE and jac <= TOLERANCE, (fk, jac)


@pytest.mark.parametrize("rel,base,tip,joints", CHAINS, ids=[f"{c[0].split('/')[-1]}:{c[2]}" for c in CHAINS])
def test_every_chain_equals_pinocchio(rel, base, tip, joints):
    path = robot(rel)
    try:
        companion.Arm.from_urdf(path, base, tip, home=mid_home(limits_from_urdf(path, joints)))
    except companion.CompanionError as e:
        # A refusal by the reader's rules names its joint; the file is read here, apart from
        # the reader, to check that the joint breaks the rule named (Centauro's wheels are
        # revolute joints with lower = upper = 0: refused, as urdfdom would treat no range).
        msg = str(e)
        m = re.search(r"joint `([^`]+)`", msg)
        assert m, msg
        import xml.etree.ElementTree as ET

        joint = next(j for j in ET.parse(path).getroot().iter("joint") if j.get("name") == m.group(1))
        lim = joint.find("limit")
        if "<limit lower upper>" in msg and "is an empty range" in msg:
            assert joint.get("type") in ("revolute", "prismatic"), msg
            assert lim is not None and float(lim.get("lower", 0)) >= float(lim.get("upper", 0)), msg
        elif "has no <limit>" in msg:
            assert lim is None, msg
        else:
            raise
        print(f"refused by rule, checked in the file: {msg}")
        return
    fk, jac = compare(rel, base, tip, seed=sum(map(ord, tip)))
    assert fk <= TOLERANCE and jac <= TOLERANCE, (fk, jac)


def test_the_tiago_arm_reads_as_the_issue_says():
    arm = companion.Arm.from_urdf(
        robot("tiago_description/robots/tiago_no_hand.urdf"),
        "base_footprint",
        "arm_tool_link",
        home=[0.2, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0],
    )
    assert arm.joints == 8 and arm.name == "tiago"
    assert arm.joint_names == ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
    assert (arm.lower[0], arm.upper[0], arm.max_velocity[0]) == (0.0, 0.35, 0.07)
    tip = arm.forward(arm.home)[:3, 3]
    # The notes' well-conditioned home: the tool 0.64 m ahead, 0.54 m up.
    assert abs(tip[0] - 0.639) < 2e-3 and abs(tip[2] - 0.5415) < 2e-3, tip
    assert np.linalg.svd(arm.jacobian(arm.home), compute_uv=False).min() > 0.2


def test_a_continuous_joint_has_no_limits():
    arm = companion.Arm.from_urdf(
        robot("pr2_description/urdf/pr2.urdf"),
        "base_footprint",
        "r_gripper_tool_frame",
        srdf=robot("pr2_description/srdf/pr2.srdf"),
        home_state="tuck_right_arm",
        home={"torso_lift_joint": 0.1},
    )
    free = [n for n, lo, hi in zip(arm.joint_names, arm.lower, arm.upper) if lo == -math.inf and hi == math.inf]
    assert free == ["r_forearm_roll_joint", "r_wrist_roll_joint"], free
    assert arm.home[0] == 0.1 and arm.home[-1] == pytest.approx(0.21436)


def test_bad_urdf_requests_raise_naming_the_link_or_joint(tmp_path):
    tiago = robot("tiago_description/robots/tiago_no_hand.urdf")
    with pytest.raises(companion.CompanionError, match="give --tip-link.*arm_tool_link"):
        companion.Arm.from_urdf(tiago, "base_footprint")
    with pytest.raises(companion.CompanionError, match="--tip-link arm_tool: .* has no such link.*did you mean"):
        companion.Arm.from_urdf(tiago, "base_footprint", "arm_tool")
    with pytest.raises(companion.CompanionError, match="need a home"):
        companion.Arm.from_urdf(tiago, "base_footprint", "arm_tool_link")
    with pytest.raises(companion.CompanionError, match="home of joint `torso_lift_joint`: 0.5 is not strictly inside"):
        companion.Arm.from_urdf(tiago, "base_footprint", "arm_tool_link", home=[0.5, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0])
    with pytest.raises(ValueError, match="q has 3 values: the arm has 8 joints"):
        companion.Arm.from_urdf(tiago, "base_footprint", "arm_tool_link", home=[0.2, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0]).forward(
            np.zeros(3)
        )
    with pytest.raises(ValueError, match="Arm.from_urdf"):
        companion.Law("unicycle", arm=str(tiago))


def test_simulate_with_an_arm_from_urdf_gives_the_cli_digest(cli, tmp_path):
    """`simulate(arm=Arm.from_urdf(...))` is `companion sim --arm robot.urdf ...`."""
    import subprocess

    tiago = robot("tiago_description/robots/tiago_no_hand.urdf")
    home = [0.2, 1.0, -0.5, -1.0, 1.2, 0.0, 0.5, 0.0]
    arm = companion.Arm.from_urdf(tiago, "base_footprint", "arm_tool_link", home=home)
    _, summary = companion.simulate(trajectory=1, platform="omni", arm=arm, duration=5.0)
    out = tmp_path / "cli"
    subprocess.run(
        [cli, "sim", "--arm", tiago, "--base-link", "base_footprint", "--tip-link", "arm_tool_link",
         "--home", ",".join(map(str, home)), "--platform", "omni", "--duration", "5", "--out", out],
        check=True, capture_output=True,
    )
    cli_summary = json.loads((out / "summary.json").read_text())
    assert summary["trajectory_digest"] == cli_summary["trajectory_digest"]
    assert summary["arm"] == "tiago" and summary["joints"] == 8
    law = companion.Law("omni", "a", arm)
    assert law.joints == 8 and law.spatial
