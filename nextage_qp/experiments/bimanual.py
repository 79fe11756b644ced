r"""Bimanual move: both end-effectors travel together, the second held to the first by a relative-frame task.

The first frame follows a straight line at constant speed; the second gets no world target at all, only the
relative pose it had to the first at the start (:class:`~nextage_qp.ik.RelativeTarget`, the coupling the
``carry`` phase puts between two clamp pads). The QP solves both arms at once, so the pair moves as one rigid
grip would; the recorded error is how far the second frame strays from that relative pose, measured on the
simulated robot (QP IK -> Ruckig -> PD -> MuJoCo).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.geometry import Pose
from nextage_qp.ik import QPIK, FrameTarget, IKConfig, RelativeTarget
from nextage_qp.loop.pd import Gains
from nextage_qp.loop.servo import Command, Servo
from nextage_qp.loop.simulation import Simulation, Timing
from nextage_qp.robots.model import Robot

SETTLE_S = 0.5
"""Rest before the move and after it [s]."""


class BimanualResult(NamedTuple):
    """Outcome of a bimanual move.

    Attributes:
        frames: The leading frame and the one coupled to it.
        max_relative_error_m: Largest deviation of the coupled frame from its relative pose, over the move [m].
        final_relative_error_m: That deviation at the end [m].
        max_relative_rot_error_rad: Largest relative orientation error over the move [rad].
        final_lead_error_m: The leading frame's distance to its goal at the end [m].
        duration_s: Simulated time [s].
    """

    frames: tuple[str, str]
    max_relative_error_m: float
    final_relative_error_m: float
    max_relative_rot_error_rad: float
    final_lead_error_m: float
    duration_s: float


def _pose(sim: Simulation, robot: Robot, frame: str) -> Pose:
    kind, fid = robot.frame(frame)
    d = sim.data
    if kind == "site":
        return Pose(d.site_xpos[fid].copy(), d.site_xmat[fid].reshape(3, 3).copy())
    return Pose(d.xpos[fid].copy(), d.xmat[fid].reshape(3, 3).copy())


def run_bimanual(robot: Robot, move: np.ndarray, *, gains: Gains, frames: tuple[str, str] | None = None,
                 speed: float = 0.05, timing: Timing | None = None,
                 ik: IKConfig | None = None) -> tuple[BimanualResult, Simulation]:
    """Move ``frames[0]`` by ``move`` [m] (world) at ``speed`` [m/s], ``frames[1]`` coupled to it; see the module doc.

    Raises:
        ConfigError: Fewer than two arms and no ``frames``, the same frame twice, or a speed that is not > 0.
        UnknownFrameError: A frame is neither a site nor a body.
    """
    if frames is None:
        if len(robot.arms) < 2:
            raise ConfigError(f"robot {robot.name!r} has one arm; a bimanual move needs two frames")
        frames = (robot.arms[0].wrist, robot.arms[1].wrist)
    lead, follow = frames
    if lead == follow:
        raise ConfigError(f"a bimanual move needs two different frames, got {lead!r} twice")
    if not speed > 0:
        raise ConfigError(f"speed must be > 0 m/s, got {speed}")
    move = np.asarray(move, dtype=float)
    if move.shape != (3,) or not np.all(np.isfinite(move)):
        raise ConfigError(f"move must be 3 finite numbers [m], got {move.tolist()}")
    robot.frame(lead), robot.frame(follow)
    sim = Simulation(robot, gains, None, timing=timing, frames=frames)
    q0 = robot.keyframe_q("home")
    sim.reset(q0)
    servo = Servo(QPIK(robot, ik or IKConfig(posture_cost=1e-3)), sim, q0)
    while sim.time < SETTLE_S - 1e-9:
        sim.tick()
    p0, p1 = _pose(sim, robot, lead), _pose(sim, robot, follow)
    relative = RelativeTarget.between(follow, lead, {lead: (p0.pos, p0.rot), follow: (p1.pos, p1.rot)}, cost=10.0)
    travel = float(np.linalg.norm(move)) / speed
    goal = p0.pos + move
    worst, worst_rot = 0.0, 0.0
    t0 = sim.time
    end = t0 + travel + SETTLE_S
    while sim.time < end - 1e-9:
        s = min((sim.time - t0) / travel, 1.0) if travel > 0 else 1.0
        target = FrameTarget(lead, pos=p0.pos + s * move, rot=p0.rot)
        servo.step(Command((target,), (relative,)))
        sim.tick()
        a, b = _pose(sim, robot, lead), _pose(sim, robot, follow)
        err = float(np.linalg.norm(a.rot.T @ (b.pos - a.pos) - relative.pos))
        rot = a.rot.T @ b.rot @ relative.rot.T
        worst = max(worst, err)
        worst_rot = max(worst_rot, float(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0))))
    result = BimanualResult((lead, follow), worst, err, worst_rot, float(np.linalg.norm(a.pos - goal)), sim.time)
    sim.recorder.meta |= {"frames": list(frames), "move_m": move.tolist(), **result._asdict()}
    return result, sim
