r"""The one control tick: a :class:`Command` in, the commanded joints ``q_cmd`` out and handed to the trajectory.

A command asks for frame poses (world or relative to another frame), or for joint positions, or for nothing
(hold). :meth:`Servo.step` turns it into joints:

* frame targets: one QP IK step gives a joint velocity :math:`v` [rad/s] at :math:`q_{cmd}`, and
  :math:`q_{cmd} \leftarrow \operatorname{clip}(q_{cmd} + s\,v\,\Delta t_{ctrl},\ q_{min},\ q_{max})` with a step
  scale :math:`s \le 1` (below);
* a joint goal: the named joints of :math:`q_{cmd}` jump to the goal (clipped to their range) and Ruckig
  shapes the motion;
* a hold: :math:`q_{cmd}` stays.

With ``ik.trust_region`` on, the step scale is a trust region that acts only on a limit cycle. The IK's
Gauss-Newton step is exact for the frame tasks' linearisation, but along joint directions that only the (weak)
posture task weighs, the frame tasks' curvature makes it overshoot: with targets that stay put, :math:`q_{cmd}`
can then jump back and forth between two configurations for ever (at 50 Hz a 20 mrad cycle at the velocity
limit, so the arm never settles). When the command is the same as on the last tick and a fast step (one joint at
``FAST`` of its velocity limit or more) turns back on the last one (cosine below ``REVERSAL``), :math:`s` halves
(down to ``MIN_SCALE``) and stays at most there while the command stays the same (a cycle of two steps each way
turns back only every other tick: growing back at once would restart it); on every other tick it doubles back
towards that cap, which a new command lifts to 1 again. Off (the default), :math:`s = 1`.

Then :math:`q_{cmd}` becomes Ruckig's target. :meth:`Servo.commanded_pose` is always the pose at the current
:math:`q_{cmd}`, so a phase that starts after a joint goal starts from where the robot is being sent.
The caller advances the simulation (``sim.tick()``) after the step.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from nextage_qp.geometry import Pose
from nextage_qp.ik import QPIK, FrameTarget, RelativeTarget
from nextage_qp.ik.kinematic_model import ObjectPoses
from nextage_qp.ik.look_at import LookAtTask
from nextage_qp.loop.simulation import Simulation
from nextage_qp.mobile.drive_models import Pose2, body_twist

REVERSAL = -0.5
"""Cosine between two successive IK steps below which the second turns back on the first."""
FAST = 0.5
"""Fraction of a joint's velocity limit x control period that a step must reach somewhere for the trust region to
act: a cycle of steps that run into the velocity box both ways, not the small back-and-forth of a converged IK."""
MIN_SCALE = 1.0 / 64.0
"""Smallest step scale of the trust region."""


@dataclass(frozen=True)
class Command:
    """What a phase asks for on one control tick.

    Attributes:
        targets: Frame targets for the IK (world poses).
        relative: Relative-pose targets between two frames (e.g. the clamp pads).
        joints: A joint goal, joint name -> angle [rad]; the IK is not stepped on such a tick.
        allow: Collision groups the IK may let touch on this tick (e.g. the object being pushed).
        posture: Joints [rad] the IK's redundancy heads for on this tick (default: the configured posture).
        base: A mobile robot's base may move on this tick (whole-body IK); otherwise its wheels hold it still.
        done: The phase has finished (this command still runs for the tick).
    """

    targets: tuple[FrameTarget, ...] = ()
    relative: tuple[RelativeTarget, ...] = ()
    joints: Mapping[str, float] | None = None
    allow: frozenset[str] = frozenset()
    posture: np.ndarray | None = None
    base: bool = False
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
        self.look: LookAtTask | None = None
        """A look-at task in every IK step (and run alone on holds): see :func:`~nextage_qp.ik.look_at.watch`."""
        self.reset(sim.ref.q if q0 is None else q0)

    def reset(self, q0: np.ndarray) -> None:
        """Set ``q_cmd`` [rad] (no motion is commanded)."""
        self._q = np.array(q0, dtype=float)
        self._last: tuple[Command, np.ndarray] | None = None  # the last IK command and its (scaled) step
        self.scale = 1.0
        """The IK step's trust-region scale (see the module doc)."""
        self._cap = 1.0  # the largest scale the region may grow back to under the current command

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
        if r.base is not None and self.sim.measured.base is not None:
            self.ik.base_pose = np.array(self.sim.measured.base, dtype=float)  # where the odometry says it is
        look = self.look if self.look is not None and self.look.point is not None else None
        if command.joints is not None:
            idx = np.array([r.joint_index(j) for j in command.joints], dtype=int)
            goal = np.fromiter(command.joints.values(), dtype=float, count=len(idx))
            held = look.dofs - self.ik.nb if look is not None else None  # the head's joints in q (no base)
            head = self._q[held].copy() if held is not None else None
            self._q[idx] = np.clip(goal, r.lower[idx], r.upper[idx])
            self._last = None
            if look is not None and head is not None:  # planned joints move the arms; the head keeps looking
                self._q[held] = head
                self._look(look)
        elif not command.holds:
            dt = self.sim.ctrl_dt
            v = self.ik.step(self._q, command.targets, dt, relative=command.relative, object_poses=object_poses,
                             allow=command.allow, posture=command.posture, extra=() if look is None else (look,),
                             base=command.base)
            dq = v * dt
            if self.ik.config.trust_region:
                dq = self._trust(command, dq, float(np.max(np.abs(v) / self.ik.box.vmax[self.ik.nb :])))
            self._q = np.minimum(np.maximum(self._q + dq, r.lower), r.upper)  # np.clip costs more
        elif look is not None:  # a hold: the head still follows its point
            self._look(look)
        if self.sim.base is not None:  # the IK's base step, through the base's inverse kinematics; else it stands
            moving = command.base and not command.holds and command.joints is None
            world = self.ik.base_velocity if moving else np.zeros(3)
            self.sim.base.command(self.sim.data, body_twist(Pose2(*self.ik.base_pose), (world[0], world[1], world[2])))
        self.sim.set_target(self._q)
        return self.q_cmd

    def _look(self, look: LookAtTask) -> None:
        """Step the head alone towards the look-at point."""
        self.ik.load(self._q)
        nb = self.ik.nb  # a mobile robot's base variables come first
        step = look.head_step(self.ik.configuration, self.ik.box.vmax * self.sim.ctrl_dt)[nb:]
        self._q = np.clip(self._q + step, self.ik.box.lower[nb:], self.ik.box.upper[nb:])

    def _trust(self, command: Command, dq: np.ndarray, speed: float) -> np.ndarray:
        """The step ``dq`` [rad] scaled by the trust region; ``speed``: its largest fraction of a velocity limit."""
        last, self._last = self._last, None
        same = last is not None and same_command(command, last[0])
        cycling = False
        if same and speed >= FAST:
            assert last is not None
            norms = float(np.linalg.norm(dq)) * float(np.linalg.norm(last[1]))
            cycling = norms > 0.0 and float(dq @ last[1]) < REVERSAL * norms
        if not same:
            self._cap = 1.0
        if cycling:
            self.scale = self._cap = max(self.scale * 0.5, MIN_SCALE)
        else:
            self.scale = min(self.scale * 2.0, self._cap)
        dq = dq * self.scale
        self._last = (command, dq)
        return dq

    def pose_at(self, frame: str, q: np.ndarray) -> Pose:
        """World pose of a frame at robot joints ``q`` [rad] (a mobile robot's base where it is believed to be)."""
        self.ik.load(q)
        pos, rot = self.ik.frame(frame).pose(self.ik.configuration.data)
        return Pose(pos.copy(), rot.copy())

    def commanded_pose(self, frame: str) -> Pose:
        """World pose of a frame at ``q_cmd`` (where the robot is being sent)."""
        if self.ik.nb or not np.array_equal(self.ik.configuration.q, self._q):
            self.ik.load(self._q)
        pos, rot = self.ik.frame(frame).pose(self.ik.configuration.data)
        return Pose(pos.copy(), rot.copy())


def _same(a: object, b: object) -> bool:
    """Equal values; arrays as :func:`numpy.array_equal` (same shape and elements), compared without its overhead."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if a is None or b is None:
            return False
        x, y = np.asarray(a), np.asarray(b)
        return x.shape == y.shape and bool((x == y).all())
    return a == b


_FIELDS: dict[type, tuple[str, ...]] = {}
"""The field names of each target class (``dataclasses.fields`` builds its tuple on every call)."""


def _field_names(cls: type) -> tuple[str, ...]:
    names = _FIELDS.get(cls)
    if names is None:
        names = _FIELDS[cls] = tuple(f.name for f in fields(cls))
    return names


def same_command(a: Command, b: Command) -> bool:
    """True when two commands ask for the same targets (frame, relative and joint), allowances and posture."""
    if len(a.targets) != len(b.targets) or len(a.relative) != len(b.relative):
        return False
    pairs: list[tuple[FrameTarget | RelativeTarget, FrameTarget | RelativeTarget]] = [
        *zip(a.targets, b.targets, strict=True), *zip(a.relative, b.relative, strict=True)]
    for x, y in pairs:
        if type(x) is not type(y) or not all(_same(getattr(x, f), getattr(y, f)) for f in _field_names(type(x))):
            return False
    return a.allow == b.allow and _same(a.posture, b.posture) and a.joints == b.joints
