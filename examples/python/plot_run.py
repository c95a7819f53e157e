"""Plot a run: companion.simulate (companion sim's own loop) and matplotlib, if installed.
Run: target/py/bin/python examples/python/plot_run.py [out.png]"""

import sys

import companion

ts, summary = companion.simulate(trajectory=1, choice="b", duration=40.0, log_every=10)
print(f"{summary['scenario']}: final |e_p| = {summary['final_ep_norm']:.2e}, digest {summary['trajectory_digest']}")
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is not installed: pip install matplotlib to draw the figure")
    sys.exit(0)

fig, (top, err) = plt.subplots(1, 2, figsize=(11, 4.5))
top.plot(ts["target"][:, 0], ts["target"][:, 1], "k--", label="target (r*_ed: 0.5 m ahead of the effector)")
top.plot(ts["end_effector"][:, 0], ts["end_effector"][:, 1], label="end effector")
top.plot(ts["base"][:, 0], ts["base"][:, 1], label="platform")
top.set(xlabel="x (m)", ylabel="y (m)", aspect="equal", title=summary["scenario"])
top.legend(loc="upper left", fontsize="small")
err.semilogy(ts["t"], ts["ep_norm"])
err.set(xlabel="t (s)", ylabel="|e_p|", title="tracking error")
out = sys.argv[1] if len(sys.argv) > 1 else "run.png"
fig.tight_layout()
fig.savefig(out, dpi=100)
print(f"wrote {out}")
