"""Run a task from Python and plot its result: the cube's distance to its target, phase by phase.

python examples/run_and_plot.py [--out push.png]
"""

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import nextage_qp as nq

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default="push.png", help="the plot (PNG)")
args = parser.parse_args()

# Any config key can be overridden, as with `nextage-qp run --set`.
result = nq.run_task("push_cube", overrides=["scene.poses.cube.yaw=0.3"])
print(f"success: {result.success}, cube {result.object_error_xy_m * 1e3:.2f} mm from its target "
      f"after {result.sim_time_s:.1f} s simulated in {result.wall_time_s:.1f} s")

rec = result.runner.sim.recorder.arrays()  # every control tick: t, q, q_ref, tau, frame and object poses
cube, target = rec["object_cube"][:, :2], np.array(result.record["target_position"][:2])
fig, ax = plt.subplots(figsize=(7, 3.5))
ax.semilogy(rec["t"], np.linalg.norm(cube - target, axis=1))
for phase in result.phases:
    ax.axvspan(phase["start_s"], phase["start_s"] + phase["duration_s"], alpha=0.1, label=phase["name"])
ax.axhline(0.005, color="k", ls="--", lw=0.8, label="success threshold")
ax.set(xlabel="time [s]", ylabel="cube to target [m]")
ax.legend()
fig.tight_layout()
fig.savefig(args.out, dpi=100)
print(f"plot: {args.out}")
