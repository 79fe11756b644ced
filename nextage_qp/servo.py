r"""The one control tick: a :class:`Command` in, the commanded joints ``q_cmd`` out and handed to the trajectory.

A command asks for frame poses (world or relative to another frame), or for joint positions, or for nothing
(hold). :meth:`Servo.step` turns it into joints:

* frame targets: one QP IK step gives a joint velocity :math:`v` [rad/s] at :math:`q_{cmd}`, and
  :math:`q_{cmd} \leftarrow \operatorname{clip}(q_{cmd} + v\,\Delta t_{ctrl},\ q_{min},\ q_{max})`;
* a joint goal: the named joints of :math:`q_{cmd}` jump to the goal (clipped to their range) and Ruckig
  shapes the motion;
* a hold: :math:`q_{cmd}` stays.

Then :math:`q_{cmd}` becomes Ruckig's target. :meth:`Servo.commanded_pose` is always the pose at the current
:math:`q_{cmd}`, so a phase that starts after a joint goal starts from where the robot is being sent.
The caller advances the simulation (``sim.tick()``) after the step.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from nextage_qp.geometry import Pose
from nextage_qp.ik import QPIK, FrameTarget, RelativeTarget
from nextage_qp.ik.model import ObjectPoses
from nextage_qp.sim import Simulation


@dataclass(frozen=True)
class Command:
    """What a phase asks for on one control tick.

    Attributes:
        targets: Frame targets for the IK (world poses).
        relative: Relative-pose targets between two frames (e.g. the clamp pads).
        joints: A joint goal, joint name -> angle [rad]; the IK is not stepped on such a tick.
        allow: Collision groups the IK may let touch on this tick (e.g. the object being pushed).
        posture: Joints [rad] the IK's redundancy heads for on this tick (default: the configured posture).
        done: The phase has finished (this command still runs for the tick).
    """

    targets: tuple[FrameTarget, ...] = ()
    relative: tuple[RelativeTarget, ...] = ()
    joints: Mapping[str, float] | None = None
    allow: frozenset[str] = frozenset()
    posture: np.ndarray | None = None
    done: bool = False

    @property
    def holds(self) -> bool:
        """True when the command moves nothing (``q_cmd`` stays)."""
        return not self.targets and not self.relative and self.joints is None


HOLD = Command()
"""Keep the commanded joints where they are."""


class Servo:
    """Owns the IK and the commanded joints ``q_cmd`` of one simulation.

    Args:
        ik: The QP IK of the simulation's robot.
        sim: The simulation whose trajectory receives ``q_cmd``.
        q0: Initial commanded joints [rad] (default: the simulation's current reference).
    """

    def __init__(self, ik: QPIK, sim: Simulation, q0: np.ndarray | None = None) -> None:
        self.ik, self.sim, self.robot = ik, sim, sim.robot
        self.reset(sim.ref.q if q0 is None else q0)

    def reset(self, q0: np.ndarray) -> None:
        """Set ``q_cmd`` [rad] (no motion is commanded)."""
        self._q = np.array(q0, dtype=float)

    @property
    def q_cmd(self) -> np.ndarray:
        """The commanded joints [rad] (a read-only view)."""
        view = self._q.view()
        view.setflags(write=False)
        return view

    def step(self, command: Command, object_poses: ObjectPoses | None = None) -> np.ndarray:
        """Apply one command for one control period; returns the new ``q_cmd`` (also sent to the trajectory).

        Raises:
            IKInfeasibleError: The IK QP of a frame command has no solution.
            UnknownJointError: A joint goal names a joint the robot does not have.
        """
        r = self.robot
        if command.joints is not None:
            idx = np.array([r.joint_index(j) for j in command.joints], dtype=int)
            goal = np.fromiter(command.joints.values(), dtype=float, count=len(idx))
            self._q[idx] = np.clip(goal, r.lower[idx], r.upper[idx])
        elif not command.holds:
            dt = self.sim.ctrl_dt
            v = self.ik.step(self._q, command.targets, dt, relative=command.relative, object_poses=object_poses,
                             allow=command.allow, posture=command.posture)
            self._q = np.clip(self._q + v * dt, r.lower, r.upper)
        self.sim.set_target(self._q)
        return self.q_cmd

    def commanded_pose(self, frame: str) -> Pose:
        """World pose of a frame at ``q_cmd`` (where the robot is being sent)."""
        if not np.array_equal(self.ik.configuration.q, self._q):
            self.ik.configuration.update(self._q)
        pos, rot = self.ik.frame(frame).pose(self.ik.configuration.data)
        return Pose(pos.copy(), rot.copy())
