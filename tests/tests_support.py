"""Helpers shared by tests (importable by name: the tests folder is on the path)."""

import numpy as np

from nextage_qp.ik import RelativeTarget
from nextage_qp.manipulation.context import Grip

NEXTAGE_JOINTS = (
    "CHEST_JOINT0",
    "HEAD_JOINT0",
    "HEAD_JOINT1",
    *(f"LARM_JOINT{i}" for i in range(6)),
    *(f"RARM_JOINT{i}" for i in range(6)),
)
"""The Nextage's 15 joints in model order (robots/nextage.yaml)."""


def held_grip_at(sim, robot, obj, shift=0.0):
    """A Grip whose pad offsets are where the pads are now in ``obj``'s frame (moved by ``shift`` [m] in x)."""
    d = sim.data
    bid = robot.model.body(obj).id
    pos, rot = d.xpos[bid], d.xmat[bid].reshape(3, 3)
    offsets = {}
    for pad in ("left_pad", "right_pad"):
        sid = robot.model.site(pad).id
        offsets[pad] = rot.T @ (d.site_xpos[sid] - pos) + np.array([shift, 0.0, 0.0])
    rel = RelativeTarget("left_pad", "right_pad", np.zeros(3), np.eye(3), 1.0)
    return Grip(obj, ("left_pad", "right_pad"), offsets, {p: np.eye(3) for p in offsets}, rel)
