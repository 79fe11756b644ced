"""The ``grasp`` phase's schema and tuning constants (the behaviour is in :mod:`.grasp`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from nextage_qp.manipulation.phases.base import MAX_SECONDS, Spec, name_field, plan_field
from nextage_qp.manipulation.route import PlanMode

SIDES = (1.0, -1.0)
"""The first pad sits on the +y side of the object's heading, the second on the -y side."""
HIGH = 0.08
"""The pads first go this far over their approach point, so the swing there passes over the object [m]."""
APPROACH_TOL = 0.006
"""The pads may stop this far from their approach waypoints [m]: near the edge of the workspace the arms reach a few
millimetres short, and the close moves the pads in anyway."""
KNOCKED = 0.3
"""Tilt of the object [rad] during the approach at which the grasp fails: the arms have knocked it over."""
OFF_CENTRE_STEP = 0.0175
"""Spacing of the clamp points tried along the faces, from the centre out to ``off_centre`` [m]."""


GRIP_STEP = 0.01
"""Step [m] by which a clamp out of reach at its default height is tried higher on the object."""
GRIP_MARGIN = 0.015
"""Least distance [m] from a raised clamp point to the object's top."""


class GraspSpec(Spec):
    """Clamp an object between two pad frames and squeeze it to a measured force."""

    grip = "makes"

    kind: Literal["grasp"]
    object: str = name_field("object", description="Free body to clamp, e.g. dumbbell.")
    frames: tuple[str, str] | None = name_field(
        "frame", default=None, description="Pads on the +y and -y side (default: the robot's arms' pads)."
    )
    half_width: float | None = Field(default=None, gt=0, le=0.5,
                                     description="Half the object's width between the pads [m] (default: from its "
                                                 "geometry at the pads' height).")
    height: float | None = Field(default=None, ge=-0.5, le=0.5,
                                 description="Pad height relative to the object origin [m] (default: the middle "
                                             "of its widest part, the highest of several).")
    gap: float = Field(default=0.03, gt=0, le=0.2, description="Pad distance from the surface before closing [m].")
    clearance: float = Field(default=0.04, gt=0, le=0.3,
                             description="Pad height over the object's top before going down beside it [m].")
    force: float = Field(default=10.0, gt=0, le=100.0, description="Squeeze force per pad [N].")
    force_per_weight: float = Field(default=0.0, ge=0, le=20.0, description=(
        "Least squeeze per pad as a multiple of the object's weight [1] (0: ``force`` alone): a heavy object held off "
        "its centre creeps about the pads' axis under a squeeze that holds a light one."))
    force_gain: float = Field(default=0.0005, gt=0, le=0.05, description="Force loop gain [m/s per N].")
    close_speed: float = Field(default=0.02, gt=0, le=0.2, description="Closing speed [m/s].")
    max_squeeze: float = Field(default=0.02, gt=0, le=0.1,
                               description="Deepest pad target inside the surface before the grasp fails [m].")
    hold: float = Field(default=0.5, ge=0, le=MAX_SECONDS, description="Time the force is held [s].")
    plan: PlanMode = plan_field()
    off_centre: float = Field(default=0.0, ge=0, le=0.2,
                              description="Farthest the pads may clamp off the centre of the faces, along them, "
                                          "where the centre is out of reach at the object or at the placement [m].")
    place_at: str | None = name_field("place", default=None,
                                      description="Body where the object will be set down: the pads take a grip "
                                                  "that reaches there too; none fails the grasp before moving.")

    @model_validator(mode="after")
    def _two_pads(self) -> GraspSpec:
        if self.frames is not None and self.frames[0] == self.frames[1]:
            raise ValueError(f"frames: {self.frames[0]!r} twice; give the two pads' frames, one on each side "
                             "of the object")
        return self
