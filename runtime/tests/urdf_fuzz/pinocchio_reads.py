"""Pinocchio's reading of the URDF fuzz's cases (runtime/tests/urdf_fuzz.rs), the second reader.

Reads a JSON list of cases on stdin and writes one JSON object a line on stdout: for each case
whether Pinocchio (urdfdom's parser) builds a model of the file, and, for a chain companion
read, the first difference from companion's reading: the moving joints from the base link to
the tip link, their limits and speeds, and the tip's pose from the base at the case's
configurations (to 1e-9, relative to the pose's size). Written apart from companion's code.
"""

import json
import math
import sys

import numpy as np
import pinocchio as pin

TOLERANCE = 1e-9


def joints_between(model, base, tip):
    stop = model.frames[model.getFrameId(base, pin.FrameType.BODY)].parentJoint
    j = model.frames[model.getFrameId(tip, pin.FrameType.BODY)].parentJoint
    out = []
    while j != stop and j > 0:
        out.append(j)
        j = model.parents[j]
    return out[::-1]


def compare(model, case):
    ids = joints_between(model, case["base"], case["tip"])
    names = [model.names[j] for j in ids]
    if names != case["joints"]:
        return f"joints {names} against companion's {case['joints']}"
    for k, j in enumerate(ids):
        jm = model.joints[j]
        lo, hi = case["limits"][k]
        if jm.nq == 1 and lo is not None:
            got = (model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q])
            if abs(got[0] - lo) > 1e-12 or abs(got[1] - hi) > 1e-12:
                return f"{names[k]}: limits {got} against companion's {(lo, hi)}"
        v = case["velocity"][k]
        if v is not None and abs(model.velocityLimit[jm.idx_v] - v) > 1e-12:
            return f"{names[k]}: speed {model.velocityLimit[jm.idx_v]} against companion's {v}"
    data = model.createData()
    base = model.getFrameId(case["base"], pin.FrameType.BODY)
    tip = model.getFrameId(case["tip"], pin.FrameType.BODY)
    for c in case["qs"]:
        q = pin.neutral(model)
        for j, x in zip(ids, c["q"]):
            jm = model.joints[j]
            if jm.nq == 2:  # a continuous joint: (cos, sin)
                q[jm.idx_q], q[jm.idx_q + 1] = math.cos(x), math.sin(x)
            else:
                q[jm.idx_q] = x
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        m = data.oMf[base].inverse() * data.oMf[tip]
        mine = np.array(c["pose"])
        theirs = np.concatenate([m.rotation.flatten(), m.translation])
        scale = max(1.0, float(np.abs(theirs[9:]).max()))
        err = float(np.abs(mine - theirs).max())
        if not err <= TOLERANCE * scale:
            return f"tip pose differs by {err:.3g} at q = {c['q']}"
    return None


def main():
    for case in json.load(sys.stdin):
        out = {"id": case["id"]}
        try:
            model = pin.buildModelFromUrdf(case["path"])
            out["ok"] = True
        except Exception as e:  # noqa: BLE001 - urdfdom's refusal, whatever it is
            out.update(ok=False, error=str(e)[:200])
        if out["ok"] and "joints" in case:
            try:
                out["mismatch"] = compare(model, case)
            except Exception as e:  # noqa: BLE001
                out["mismatch"] = f"{type(e).__name__}: {e}"[:300]
        print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
