"""A small explore grid from Python: the paper's variants a–d on the three platforms, 40 s of
trajectory 1 each, one row per run (what `companion explore` classifies runs by: the final
error and the share of steps tracked). Run: target/py/bin/python examples/python/grid.py"""

import companion

print(f"{'platform':<9} {'choice':<6} {'final |e_p|':>12} {'tracked > 20 s':>15} {'rejected':>9}")
for platform in ["unicycle", "car", "omni"]:
    for choice in "abcd":
        try:
            _, s = companion.simulate(1, choice, platform, duration=40.0, log_every=1000)
        except companion.CompanionError as e:  # e.g. a preset the platform refuses
            print(f"{platform:<9} {choice:<6} refused: {type(e).__name__}: {e}")
            continue
        tracked = s["fraction_ep_below_1e-3_after_20s"]
        print(f"{platform:<9} {choice:<6} {s['final_ep_norm']:>12.2e} {100 * tracked:>14.1f}% {s['rejected_steps']:>9}")
