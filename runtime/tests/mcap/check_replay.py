#!/usr/bin/env python3
"""Reads a `companion ... --mcap FILE` replay with the `mcap` package from PyPI (Foxglove's
Python reader, independent of the Rust writer) and checks it.

    check_replay.py FILE [--csv timeseries.csv] [--platform unicycle|car|omni]

Checks: the file's summary (a finished file: footer, indexes, statistics); the five channels,
their topics, message encoding `json`, schema names and schema encoding `jsonschema`, each
schema parseable JSON with its title equal to the schema name; the same number of messages on
every topic; log times non-decreasing per topic and in file order, equal across topics at
each frame and equal to each message's `timestamp`. With --csv: one frame per CSV row, and
the decoded values against the CSV's columns — the time, the platform pose (from the `/tf`
quaternion), the joints, the target, the end effector *as the composition of the transform
chain world→base→link1→…→effector*, the command, ‖e_p‖ (and the norm of the e_p
components), the status.

Prints one line of JSON with the counts on success; exits 1 with the reasons otherwise.
"""

import csv
import json
import math
import sys

from mcap.reader import make_reader

EXPECTED = {
    "/tf": "foxglove.FrameTransforms",
    "/scene": "foxglove.SceneUpdate",
    "/joint_states": "foxglove.JointStates",
    "/command": "companion.Command",
    "/tracking_error": "companion.TrackingError",
}
PLATFORM_COMMAND = {
    "unicycle": ["v", "omega"],
    "car": ["v", "omega", "v_xi"],
    "omni": ["v", "v_lat", "omega"],
}

problems = []


def check(ok, what):
    if not ok:
        problems.append(what)
    return ok


def close(a, b, tol):
    return a is not None and b is not None and abs(a - b) <= tol * max(1.0, abs(b))


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def rotate(q, v):
    x, y, z, w = q
    p = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), (-x, -y, -z, w))
    return p[:3]


def compose(a, b):
    """Poses as (translation, quaternion): a then b."""
    (ta, qa), (tb, qb) = a, b
    r = rotate(qa, tb)
    return ((ta[0] + r[0], ta[1] + r[1], ta[2] + r[2]), quat_mul(qa, qb))


def yaw(q):
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def stamp_ns(m):
    return m["sec"] * 1_000_000_000 + m["nsec"]


def main():
    args = sys.argv[1:]
    path = args[0]
    csv_path = args[args.index("--csv") + 1] if "--csv" in args else None
    platform = args[args.index("--platform") + 1] if "--platform" in args else "unicycle"

    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        if not check(summary is not None, "no summary section: the file was not finished"):
            return
        topics = {}
        for cid, ch in summary.channels.items():
            schema = summary.schemas[ch.schema_id]
            topics[ch.topic] = cid
            check(ch.message_encoding == "json", f"{ch.topic}: message encoding {ch.message_encoding}")
            check(schema.encoding == "jsonschema", f"{ch.topic}: schema encoding {schema.encoding}")
            check(EXPECTED.get(ch.topic) == schema.name, f"{ch.topic}: schema {schema.name}")
            text = json.loads(schema.data)
            check(text.get("title") == schema.name, f"{ch.topic}: schema title {text.get('title')}")
        check(sorted(topics) == sorted(EXPECTED), f"topics {sorted(topics)}")
        counts = summary.statistics.channel_message_counts
        by_topic = {t: counts.get(topics[t], 0) for t in topics}

        frames = {t: [] for t in EXPECTED}
        last = -1
        for _schema, ch, m in reader.iter_messages(log_time_order=False):
            check(m.log_time >= last, f"{ch.topic}: log time {m.log_time} after {last} in file order")
            last = m.log_time
            check(m.publish_time == m.log_time, f"{ch.topic}: publish time differs")
            frames[ch.topic].append((m.log_time, json.loads(m.data)))

    n = len(frames["/tf"])
    for t, msgs in frames.items():
        check(len(msgs) == n, f"{t}: {len(msgs)} messages, /tf {n}")
        check(by_topic.get(t) == len(msgs), f"{t}: statistics say {by_topic.get(t)}, read {len(msgs)}")
    check(n > 0, "no messages")
    for k in range(n):
        times = {t: frames[t][k][0] for t in frames}
        check(len(set(times.values())) == 1, f"frame {k}: log times differ {times}")
        for t in ("/tf", "/joint_states", "/command", "/tracking_error"):
            msg = frames[t][k][1]
            stamp = msg["transforms"][0]["timestamp"] if t == "/tf" else msg["timestamp"]
            check(stamp_ns(stamp) == frames[t][k][0], f"{t} frame {k}: timestamp differs from log time")
        if k > 0:
            check(frames["/tf"][k][0] > frames["/tf"][k - 1][0], f"frame {k}: time does not increase")

    rows = 0
    if csv_path:
        with open(csv_path, newline="") as f:
            table = list(csv.DictReader(f))
        rows = len(table)
        check(rows == n, f"{rows} CSV rows, {n} frames")
        # A spatial run's CSV (`sim --arm ur5|panda|FILE`) has the effector's and the target's
        # height and quaternion, and e_p's six components.
        spatial = "z_e" in table[0] if table else False
        joint_names = [c for c in (table[0].keys() if table else []) if c[:1] == "q" and c[1:].isdigit()]
        for k, row in enumerate(table[:n]):
            g = lambda c: float(row[c])  # noqa: E731
            t_ns, tf = frames["/tf"][k]
            check(abs(t_ns - g("t") * 1e9) <= 1.0, f"row {k}: time {t_ns} ns vs t = {row['t']}")
            pose = {}
            chain = []
            for x in tf["transforms"]:
                tr, q = x["translation"], x["rotation"]
                pose[(x["parent_frame_id"], x["child_frame_id"])] = (
                    (tr["x"], tr["y"], tr["z"]),
                    (q["x"], q["y"], q["z"], q["w"]),
                )
                chain.append((x["parent_frame_id"], x["child_frame_id"]))
            base = pose[("world", "base")]
            check(close(base[0][0], g("x_b"), 1e-12) and close(base[0][1], g("y_b"), 1e-12), f"row {k}: base")
            check(abs(wrap(yaw(base[1]) - g("theta_b"))) < 1e-9, f"row {k}: base heading")
            target = pose[("world", "target")]
            check(close(target[0][0], g("x_d"), 1e-12) and close(target[0][1], g("y_d"), 1e-12), f"row {k}: target")
            # The effector: compose the chain from the world down.
            frame, acc = "base", base
            while frame != "effector":
                child = next(c for (p, c) in chain if p == frame)
                acc = compose(acc, pose[(frame, child)])
                frame = child
            z_e = g("z_e") if spatial else 0.0
            check(
                close(acc[0][0], g("x_e"), 1e-9) and close(acc[0][1], g("y_e"), 1e-9) and abs(acc[0][2] - z_e) < 1e-9,
                f"row {k}: effector {acc[0]} vs ({row['x_e']}, {row['y_e']}, {z_e})",
            )
            if spatial:
                check(close(target[0][2], g("z_d"), 1e-12), f"row {k}: target height")
                # The same rotation: q and −q are one; |<q, q_csv>| = 1.
                dot = sum(a * g(c) for a, c in zip(acc[1], ("qx_e", "qy_e", "qz_e", "qw_e")))
                check(abs(abs(dot) - 1.0) < 1e-9, f"row {k}: effector rotation (|<q, q_csv>| = {abs(dot)})")
            else:
                check(abs(wrap(yaw(acc[1]) - g("theta_e"))) < 1e-9, f"row {k}: effector heading")
            joints = frames["/joint_states"][k][1]["joints"]
            check([j["name"] for j in joints] == joint_names, f"row {k}: joint names")
            for j in joints:
                check(j["position"] == g(j["name"]), f"row {k}: {j['name']} {j['position']} vs {row[j['name']]}")
            cmd = frames["/command"][k][1]
            check(sorted(cmd["platform"]) == sorted(PLATFORM_COMMAND[platform]), f"row {k}: command fields")
            for name in ("v", "omega", "v_lat", "v_xi"):
                if name in cmd["platform"] and name in row:
                    check(cmd["platform"][name] == g(name), f"row {k}: command {name}")
            check(cmd["status"] == row["status"], f"row {k}: status {cmd['status']} vs {row['status']}")
            err = frames["/tracking_error"][k][1]
            check(err["norm"] == g("ep_norm"), f"row {k}: norm {err['norm']} vs {row['ep_norm']}")
            e = err["e_p"]
            names = ("x", "y", "z", "rx", "ry", "rz") if spatial else ("x", "y", "theta")
            check(sorted(e) == sorted(names), f"row {k}: e_p components {sorted(e)}")
            norm = math.sqrt(sum(e.get(c, math.nan) ** 2 for c in names))
            if spatial:
                for c in names:
                    check(e.get(c) == g("ep_" + c), f"row {k}: e_p {c} {e.get(c)} vs {row['ep_' + c]}")
            check(abs(norm - g("ep_norm")) <= 1e-9, f"row {k}: |e_p| {norm} vs {row['ep_norm']}")
            if len(problems) > 20:
                break

    if problems:
        print("\n".join(problems[:20]), file=sys.stderr)
        sys.exit(1)
    print(json.dumps({"frames": n, "topics": by_topic, "csv_rows": rows, "last_ns": last}))


if __name__ == "__main__":
    main()
