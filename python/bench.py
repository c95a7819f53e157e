"""Benchmark (not a test): the cost of stepping the law from Python against the Rust step, in
the same process on the same measurements.

- one `Law.step` from Python (a prebuilt `Measurement`; the call, the conversion and the
  `Output`), p50 over the run, against the Rust step alone (`Law.time_rust_steps`: the same law
  stepped in a Rust loop, each step timed), p50;
- `LawBatch.step` over 1 000 laws: the call's time per law step, against the Rust step's p50.

For the planar unicycle law (run (a), trajectory 1) and the UR5 (lifted trajectory 1).
Run: target/py/bin/python python/bench.py (after scripts/setup).
"""

import time

import numpy as np

import companion

DT = 0.001
STEPS = 5000
LAWS = 1000
BATCH_CALLS = 20


def planar_rows():
    plant, law = companion.Plant(1, "a", "unicycle"), companion.Law("unicycle", "a")
    rows = []
    for _ in range(STEPS):
        m = plant.measure()
        rows.append(m.row)
        plant.advance(law.step(m, DT).command, DT)
    return np.array(rows)


def ur5_rows():
    ts, _ = companion.simulate(1, "a", arm="ur5", duration=STEPS * DT, log_every=1)
    n = len(ts["t"]) - 1
    target = ts["target"][:n]
    return np.column_stack(
        [
            ts["t"][:n],
            ts["base"][:n],
            ts["steering"][:n],
            ts["joints"][:n],
            target[:, :3, :3].reshape(n, 9),
            target[:, :3, 3],
            ts["target_twist"][:n],
        ]
    )


def bench(name, make_law, make_batch, rows):
    rust = make_law().time_rust_steps(rows, DT)
    law = make_law()
    measurements = [row.copy() for row in rows]
    py = np.empty(len(rows))
    for i, m in enumerate(measurements):
        t0 = time.perf_counter_ns()
        law.step(m, DT)
        py[i] = time.perf_counter_ns() - t0
    batch = make_batch(LAWS)
    per_law = []
    for k in range(BATCH_CALLS):
        block = np.ascontiguousarray(np.repeat(rows[k : k + 1], LAWS, axis=0))
        t0 = time.perf_counter_ns()
        batch.step(block, DT)
        per_law.append((time.perf_counter_ns() - t0) / LAWS)
    r50, p50, b50 = np.median(rust), np.median(py), np.median(per_law)
    print(
        f"{name:<14} Rust step p50 {r50 / 1e3:6.2f} us | Law.step from Python p50 {p50 / 1e3:6.2f} us ({p50 / r50:4.2f}x) | "
        f"LawBatch per law step {b50 / 1e3:6.2f} us ({b50 / r50:4.2f}x the Rust p50)"
    )


if __name__ == "__main__":
    print(f"companion {companion.__version__}: {STEPS} steps, batch of {LAWS} laws x {BATCH_CALLS} calls")
    bench("unicycle rpr", lambda: companion.Law("unicycle", "a"), lambda n: companion.LawBatch(n, "unicycle", "a"), planar_rows())
    bench("unicycle ur5", lambda: companion.Law("unicycle", "a", "ur5"), lambda n: companion.LawBatch(n, "unicycle", "a", "ur5"), ur5_rows())
