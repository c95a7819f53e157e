"""Step the law in your own loop: the simulator's plant, the law stepped from Python, 10 s of
the paper's run (a) on trajectory 1. Run: target/py/bin/python examples/python/step_loop.py"""

import companion

dt = 0.001  # s
law = companion.Law("unicycle", "a")  # the planar RPR arm, f64, the paper's preset
plant = companion.Plant(trajectory=1, choice="a", platform="unicycle")
for n in range(10_001):
    out = law.step(plant.measure(), dt)  # raises a companion.StepError subclass on a bad measurement
    if n % 2000 == 0:
        print(f"t = {plant.t:5.1f} s   |e_p| = {plant.ep_norm:.2e}   v = {out.v:+.3f} m/s   omega = {out.omega:+.3f} rad/s")
    plant.advance(out.command, dt)
