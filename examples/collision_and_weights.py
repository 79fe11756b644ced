"""A collision pair and a task weight of your own: the right arm kept 10 cm off the table, orientation weighed less.

    python examples/collision_and_weights.py

The IK's collision pairs name collision groups (the robot file's, the scene's table and obstacle, one per object);
``ik.orientation_cost`` weighs every orientation target [1/rad] against positions [1/m].
"""

import mujoco
import numpy as np

import nextage_qp as nq

pairs = ("[{a: left_hand, b: table, min_distance: 0.008, detection_distance: 0.05},"
         " {a: left_forearm, b: cube, min_distance: 0.01, detection_distance: 0.04},"
         " {a: left_arm, b: torso, min_distance: 0.01, detection_distance: 0.05},"
         " {a: right_arm, b: table, min_distance: 0.10, detection_distance: 0.15},"   # yours: 10 cm
         " {a: left_arm, b: right_arm, min_distance: 0.01, detection_distance: 0.05}]")
task = nq.load_task("push_cube", overrides=[f"ik.collision_pairs={pairs}", "ik.orientation_cost=0.5"])

closest = []


def watch(tick: nq.Tick) -> None:
    """Every tick: the right arm's distance to the table, as MuJoCo measures it."""
    sim, robot = tick.runner.sim, tick.runner.robot
    groups = robot.collision_geoms()
    table = groups["table"][0]
    closest.append(min(mujoco.mj_geomDistance(robot.model, sim.data, g, table, 1.0, None) for g in groups["right_arm"]))


result = task.run(on_tick=watch)
print(f"success: {result.success}, cube {result.object_error_xy_m * 1e3:.2f} mm off; the right arm came no closer "
      f"than {min(closest) * 1e3:.0f} mm to the table")
assert result.success and np.min(closest) > 0.09, result.error
