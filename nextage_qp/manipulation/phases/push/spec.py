"""The ``push`` phase's schema and tuning constants (the behaviour is in :mod:`.push`)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from nextage_qp.manipulation.phases.base import MAX_SECONDS, Spec, name_field, plan_field
from nextage_qp.manipulation.route import PlanMode

PUSH_ACCEL = 0.1
"""Acceleration of the push speed [m/s²]."""
STEER_GAIN = 0.5
"""Integral gain of the push's heading bias per radian of object-motion error [1/s]."""
MAX_BIAS = 0.35
"""Largest heading bias between the push and the object's bearing to the target [rad]."""
MIN_STEER_SPEED = 0.005
"""Object speed above which its motion direction is trusted for steering [m/s]."""
VELOCITY_WINDOW = 0.2
"""Time constant of the object's velocity estimate [s]."""
HEIGHT_GAIN = 5.0
"""Integral gain of the tool-height hold while pushing [1/s]."""
MAX_HEIGHT_BIAS = 0.01
"""Largest correction of the commanded tool height while pushing [m]."""
GAP_TIME = 0.5
"""Before contact the tool closes the gap to the object in about this time [s] (slowly at the touch)."""
HIDDEN_S = 0.2
"""While the wrist feels the push, an object no camera has measured for this long [s] is taken to be where the
contact puts it: its face on the tool along the push."""
PRESS_M = 0.005
"""A tool this far [m] past the object's estimated face while the wrist feels nothing has moved it (a light object
slides under less force than the sensor's threshold; or the estimate fell short): an object cannot be inside the tool,
so the push then carries the estimate as if felt."""
FULL_ORIENT_JOINTS = 7
"""Joints that must move a tool for ``orient: auto`` to hold its whole rotation: six place the face and its normal;
the roll about the normal needs one more (a torso joint counts)."""
LOOK_S = 2.0
"""After backing off from a push the camera could not see, wait at most this long [s] for a view before judging it."""
SEEN_S = 0.4
"""A push judged after looking is judged once the camera has seen the object this long [s]: the estimate that
followed the hand while it hid the object takes a few frames to move to what the camera sees."""
BLIND_S = 5.0
"""A push no camera has seen for this long [s] stops to look, however far it went (``blind``: one stalled unseen)."""
ASIDE = 0.15
"""Looking at a push the camera could not see, the tool moves this far [m] towards the robot's side, level, after
backing off."""
LOOK_AGAIN = 2
"""Times the tool moves on by ``ASIDE`` when the camera still does not see the object ``LOOK_S`` after the last move:
judged on an estimate unseen for seconds, a push may be taken for centimetres off (an estimate coasts on after a
partial view as the hand rises)."""
STUCK_S = 10.0
"""A push in contact whose object comes no ``STUCK_M`` nearer its target for this long [s] is stuck (the arm held by
an obstacle it must keep clear of, say): the tool backs off and approaches again."""
STUCK_M = 0.002
"""Progress [m] towards the target that counts as the push moving."""
TIPPING_SHARE = 0.25
"""A push that times out having paused this share of its ``timeout`` for a tipping object says so."""
LOST_GAP = 0.03
"""An object this far [m] beyond the approach gap, or off the tool face, was knocked away: approach it again."""


class PushSpec(Spec):
    """Push an object onto a target with one tool frame, steering from the object's live pose."""

    kind: Literal["push"]
    frame: str = name_field("frame", description="Tool frame that pushes: an arm's tool frame of the robot file.")
    object: str = name_field("object", description="Free body to push, e.g. cube.")
    target: str = name_field("place", description="Body marking where the object should end, e.g. cube_target.")
    other_frames: tuple[str, ...] = name_field(
        "frame", default=(), description="Other tool frames (e.g. the other arm's) that may take over a correction: "
        "it is made by the tool that reaches the direction nearest the error (ties: the tool pushing), the other one "
        "going home.")
    height: float | None = Field(default=None, ge=-0.2, le=0.2,
                                 description="Tool height over the object centre [m] (unset: the robot file's "
                                             "push_face, else 0).")
    approach: float = Field(default=0.04, gt=0, le=0.3, description="Gap behind the object before a push [m].")
    clearance: float = Field(default=0.07, gt=0, le=0.5, description="Height over the object's top in transit [m].")
    tolerance: float = Field(default=0.002, gt=0, le=0.1, description="Planar error that ends the phase [m].")
    accept: float = Field(default=0.005, gt=0, le=0.2, description="Error accepted when no try is left [m].")
    attempts: int = Field(default=4, ge=1, le=20, description="Approaches [count] (the first push and re-approaches).")
    nudges: int = Field(default=3, ge=0, le=20, description="Resumed pushes on the same line per approach [count].")
    recoveries: int = Field(default=2, ge=0, le=20,
                            description="Extra approaches after the object was knocked away from "
                                        "the tool's line [count].")
    speed: float = Field(default=0.15, gt=0, le=1.0, description="Transit speed [m/s].")
    push_speed: float = Field(default=0.05, gt=0, le=0.5, description="Top speed in contact [m/s].")
    creep_speed: float = Field(default=0.005, gt=0, le=0.1, description="Speed at the target [m/s].")
    slow_down: float = Field(default=0.04, gt=0, le=0.5, description="Distance over which the push slows [m].")
    preload: float = Field(default=0.012, gt=0, le=0.05, description="Lead of the tool into the object [m].")
    turn_rate: float = Field(default=0.5, gt=0, le=5.0, description="Turn rate of the push direction [rad/s].")
    freeze: float = Field(default=0.04, ge=0, le=0.2, description="Distance inside which the direction is kept [m].")
    centre_band: float = Field(default=0.01, ge=0, le=0.1,
                               description="Offset of the object along the tool face left alone [m].")
    max_tilt: float = Field(default=0.07, gt=0, le=1.0,
                            description="Object tilt above which the push pauses until it is flat again [rad].")
    settle: float = Field(default=0.3, ge=0, le=MAX_SECONDS, description="Rest before the error is judged [s].")
    yaw: float = Field(default=0.0, ge=-np.pi, le=np.pi, description="Tool yaw relative to the push [rad].")
    plan: PlanMode = plan_field()
    orient: Literal["auto", "full", "normal"] = Field(
        default="auto", description="Hold the tool's whole rotation (x: the push, z: up), or only its face normal "
                                    "(x) along the push, a roll left free; auto: the whole rotation where at least "
                                    f"{FULL_ORIENT_JOINTS} joints move every pushing tool, else the normal.")
    pitch: float | None = Field(default=None, ge=-0.8, le=0.8,
                                description="Tool pitch [rad]; > 0 tilts the push face's normal down (unset: the "
                                            "robot file's push_face, else 0).")
    standoff: float = Field(default=0.004, ge=0, le=0.05,
                            description="The first push stops this short of the target; a short push aimed from "
                                        "the side the error then points to finishes the job [m].")
    square: float = Field(default=0.0, ge=0, le=0.5,
                          description="A first push from more than twice this far whose reachable approach deviates "
                                      "more than correction_fan from its line to the target stops this far [m] from "
                                      "the target, where a tool reaches an approach within correction_fan of the "
                                      "line, and the tool approaches again from straight behind the object's line "
                                      "(no new attempt): a long slanted push leaves an error across the line that "
                                      "only a sideways correction removes. 0: off, the slanted push goes all the way.")
    blind: float = Field(default=0.12, gt=0, le=5.0,
                         description="Longest push no camera sees (the hand hides the object) [m]: it then stops, "
                                     "looks, and goes on from where the object is (not a new attempt).")
    look_to_judge: bool = Field(
        default=False, description="Judge every push only after backing off and seeing the object clear of the hand "
                                   "(as a push the hand hid is judged): for a camera whose view of the object is "
                                   "unreliable beside the hand (stereo depth smears the hand's edge into it).")
    correction_fan: float = Field(default=0.53, ge=0, le=1.6,
                                  description="Largest deviation from the error's direction for a correction [rad].")
    fan: tuple[float, ...] = Field(
        default=(0.0, 0.2618, 0.5236, 0.7854, 1.0472), min_length=1,
        description="Deviations from the line to the target tried, each way, when its approach is out of reach [rad].",
    )

    @model_validator(mode="after")
    def _accept_covers_tolerance(self) -> PushSpec:
        if self.accept < self.tolerance:
            raise ValueError(f"accept ({self.accept} m) must be >= tolerance ({self.tolerance} m)")
        if self.creep_speed > self.push_speed:
            raise ValueError(f"creep_speed ({self.creep_speed}) must be <= push_speed ({self.push_speed})")
        return self
