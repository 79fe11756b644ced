"""A phase kind of your own: the tool draws a horizontal circle, then a task config uses it from YAML.

    python examples/custom_phase.py

A phase kind is a spec (its YAML keys, validated like every config: a typo is a one-line error) and a behaviour
(``start`` once, then ``update`` every control tick, returning the command for the whole-body IK).
"""

import math
from typing import Literal

import numpy as np
from pydantic import Field

import nextage_qp as nq
from nextage_qp.ik import FrameTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.phases.base import Phase, Spec, name_field


class CircleSpec(Spec):
    """Draw a horizontal circle with a frame, around where it starts."""

    kind: Literal["circle"]
    frame: str = name_field("frame", description="The frame that draws (a site of the robot).")
    radius: float = Field(default=0.05, gt=0, le=0.3, description="[m]")
    period: float = Field(default=4.0, gt=0, description="One turn [s].")
    turns: float = Field(default=1.0, gt=0, description="How many.")


class Circle(Phase):
    """The frame's target moves around the circle; the orientation it started with is held."""

    spec: CircleSpec

    def start(self, view) -> None:  # noqa: D102 (the Phase contract)
        self.t0 = view.t
        self.start_pose = view.commanded_pose(self.spec.frame)
        self.deviation = 0.0

    def update(self, view) -> Command:  # noqa: D102
        c = self.spec
        angle = 2 * math.pi * (view.t - self.t0) / c.period
        centre = self.start_pose.pos - np.array([c.radius, 0.0, 0.0])
        point = centre + c.radius * np.array([math.cos(angle), math.sin(angle), 0.0])
        # how far the measured frame is from the circle, as the phase's own figure in the result
        measured = view.frame_pose(c.frame).pos
        self.deviation = max(self.deviation, abs(np.linalg.norm((measured - centre)[:2]) - c.radius))
        self.info["max_deviation_m"] = round(self.deviation, 5)
        done = angle >= 2 * math.pi * c.turns
        return Command((FrameTarget(c.frame, pos=point, rot=self.start_pose.rot),), done=done)


nq.register_phase(CircleSpec, Circle)
# The push task's scene and settings, with the circle as its only phase (any YAML config may now say kind: circle).
task = nq.load_task("push_cube", overrides=[
    "task=draw_circle",
    "phases=[{kind: circle, frame: right_tool, radius: 0.06, period: 3.0, turns: 1}]",
    "success.planar_error=1.0",  # the cube is not moved: judge the drawing, not the cube
])
result = task.run()
circle = result.phases[0]
print(f"{circle['status']}: the tool stayed within {circle['max_deviation_m'] * 1e3:.1f} mm of its circle "
      f"({circle['duration_s']:.1f} s)")
assert result.success, result.error
