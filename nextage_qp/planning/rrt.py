"""Collision-free joint paths: OMPL's RRT-Connect over the joints a motion moves, shortcut, checked densely.

:func:`plan_path` plans from one robot configuration to another in the joint space of the joints that differ
between them (one arm; both arms and the torso for a carried object), the others held where they are. The
validity check is the project's own (:class:`~nextage_qp.planning.world.CollisionWorld`); OMPL checks each motion
at a resolution of its own, and the simplified path is then checked again densely, at a few millimetres of the
fastest-moving point, before it is returned.

Runs repeat: OMPL's random numbers are seeded before every plan (``seed``), and the simplification runs a fixed
number of steps, not for a time.
"""

from __future__ import annotations

import atexit
import gc
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydantic import Field

from nextage_qp.io.schema import YamlModel
from nextage_qp.planning.world import Collision, CollisionWorld

MOVES = 1e-6
"""A joint moves when start and goal differ by more than this [rad]."""
OMPL_RESOLUTION = 0.002
"""OMPL's motion checks: the share of the joint space's extent between two checked states."""
SHORTCUT_STEPS = 60
"""Random shortcut attempts of the simplification (a fixed number: a plan repeats on any machine)."""
ESCAPE = (0.02, 0.05, 0.1, 0.2)
"""Joint radii [rad], in turn, within which a valid state is sought near a start in collision (:func:`escape`)."""
ESCAPE_SAMPLES = 40
"""Random states tried per radius of :data:`ESCAPE`."""
ESCAPE_SLACK = 0.001
"""How much deeper [m] than at the start the way out of a start in collision may reach (the check's rounding)."""


class PlanningConfig(YamlModel):
    """How transits are planned: the clearance kept and the time a plan may take."""

    clearance: float = Field(default=0.01, ge=0, le=0.2, allow_inf_nan=False,
                             description="Least distance [m] a planned path keeps from obstacles and objects.")
    table_clearance: float = Field(default=0.0, ge=0, le=0.2, allow_inf_nan=False,
                                   description="Least distance [m] a planned path keeps from the table (0: no "
                                               "penetration).")
    time_limit: float = Field(default=1.0, gt=0, le=60, allow_inf_nan=False,
                              description="Time [s] of wall clock a plan may take before the goal counts as "
                                          "unreachable.")


@dataclass
class PathPlan:
    """A planned joint path, or why there is none.

    Attributes:
        path: Robot joint waypoints [rad], start first and goal last (empty when none was found).
        status: ``straight`` (the straight segment is free), ``planned``, ``invalid_start``, ``invalid_goal`` or
            ``no_path``.
        why: For an invalid start or goal, what collides there.
        time_s: Wall time spent planning [s].
        checks: States checked.
        joints: Indices of the robot joints the plan moved.
    """

    path: list[np.ndarray]
    status: str
    why: Collision | None = None
    time_s: float = 0.0
    checks: int = 0
    joints: tuple[int, ...] = field(default_factory=tuple)

    @property
    def found(self) -> bool:
        """Whether there is a path."""
        return self.status in ("straight", "planned")

    def reason(self) -> str:
        """Why there is no path, in words (empty when there is one)."""
        if self.status == "invalid_start":
            return f"the start puts {self.why}"
        if self.status == "invalid_goal":
            return f"the goal puts {self.why}"
        if self.status == "no_path":
            return f"no collision-free path found in {self.time_s:.1f} s ({self.checks} states checked)"
        return ""


def plan_path(world: CollisionWorld, q_start: np.ndarray, q_goal: np.ndarray, *, lower: np.ndarray,
              upper: np.ndarray, time_limit: float = 1.0, seed: int = 1, straight_first: bool = True,
              joints: Sequence[int] | None = None, escape_start: bool = False) -> PathPlan:
    """A collision-free joint path from ``q_start`` to ``q_goal`` (robot joint vectors [rad]).

    The straight segment is taken when it is free (``straight_first``); else RRT-Connect plans within
    ``time_limit`` [s] in the space of ``joints`` (default: those that differ between start and goal; a caller
    passes whole arms, which may move aside where the joints that must move cannot pass), bounded by ``lower`` and
    ``upper``, and the path is shortcut and checked densely.

    With ``escape_start`` (the start is where the robot stands), a start in collision (as the world is believed: a
    seen box drawn around a piece of clutter a voxel wider than the piece) is left first, along the straight segment
    to the nearest valid state found nearby (:func:`escape`), as MoveIt's start-state fix does; the path is planned
    from there. Without it such a start is ``invalid_start``.
    """
    t0, checks0 = time.perf_counter(), world.checks
    qa, qb = np.asarray(q_start, dtype=float), np.asarray(q_goal, dtype=float)
    differ = {int(j) for j in np.flatnonzero(np.abs(qb - qa) > MOVES)}
    moving = tuple(sorted(differ | set(joints or ())))

    def done(path: list[np.ndarray], status: str, why: Collision | None = None) -> PathPlan:
        return PathPlan(path, status, why, time.perf_counter() - t0, world.checks - checks0, moving)

    if (why := world.first_collision(qa)) is not None:
        out = escape(world, qa, moving, lower, upper, seed) if escape_start else None
        if out is None:
            return done([], "invalid_start", why)
        rest = plan_path(world, out, qb, lower=lower, upper=upper, time_limit=time_limit - (time.perf_counter() - t0),
                         seed=seed, straight_first=straight_first, joints=joints, escape_start=False)
        return done([qa, *rest.path], "planned", None) if rest.found else done([], rest.status, rest.why)
    if (why := world.first_collision(qb)) is not None:
        return done([], "invalid_goal", why)
    if straight_first and world.first_on_segment(qa, qb) is None:
        return done([qa, qb], "straight")
    if not differ:
        return done([qa, qb], "straight")
    for attempt in range(3):  # a path the dense check refutes is planned again, from another seed, checked finer
        left = time_limit - (time.perf_counter() - t0)  # the attempts share the time limit
        if left <= 0:
            break
        path = _ompl(world, qa, qb, moving, lower, upper, left, seed + attempt, OMPL_RESOLUTION / 2**attempt)
        if path is None:
            return done([], "no_path")
        if world.first_on_path(path) is None:
            return done(path, "planned")
    return done([], "no_path")


def escape(world: CollisionWorld, q: np.ndarray, moving: Sequence[int], lower: np.ndarray, upper: np.ndarray,
           seed: int) -> np.ndarray | None:
    """A valid state near ``q`` (in collision), reached from it without going deeper in, or None.

    Random states of the ``moving`` joints within each radius of :data:`ESCAPE` in turn (``ESCAPE_SAMPLES`` each,
    seeded: a run repeats); of those valid whose straight segment from ``q`` never reaches deeper than ``q`` is (by
    more than ``ESCAPE_SLACK``), the nearest.
    """
    if not moving:
        return None
    rng = np.random.default_rng(seed)
    idx = np.asarray(moving, dtype=int)
    depth = world.room(q)[0]
    for radius in ESCAPE:
        found = []
        for _ in range(ESCAPE_SAMPLES):
            cand = q.copy()
            cand[idx] = np.clip(q[idx] + rng.uniform(-radius, radius, len(idx)), lower[idx], upper[idx])
            if world.valid(cand) and _leaves(world, q, cand, depth):
                found.append(cand)
        if found:
            return min(found, key=lambda c: float(np.abs(c - q).max()))
    return None


def _leaves(world: CollisionWorld, qa: np.ndarray, qb: np.ndarray, depth: float) -> bool:
    """Whether the straight segment from ``qa`` (room ``depth`` [m], < 0) to ``qb`` never reaches deeper."""
    n = world.steps(qa, qb)
    return all(world.room(qa + (k / n) * (qb - qa))[0] >= depth - ESCAPE_SLACK for k in range(1, n))


def _ompl(world: CollisionWorld, qa: np.ndarray, qb: np.ndarray, moving: Sequence[int], lower: np.ndarray,
          upper: np.ndarray, time_limit: float, seed: int, resolution: float) -> list[np.ndarray] | None:
    """RRT-Connect and its simplification over the ``moving`` joints; None when no path is found in time."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(seed)  # before any of this plan's samplers exist: the plan repeats
    idx = list(moving)
    n = len(idx)
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for k, j in enumerate(idx):
        lo, hi = min(lower[j], qa[j], qb[j]), max(upper[j], qa[j], qb[j])
        bounds.setLow(k, float(lo))
        bounds.setHigh(k, float(hi))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    q = qa.copy()

    def valid(state: object) -> bool:
        for k, j in enumerate(idx):
            q[j] = state[k]  # type: ignore[index]
        return world.valid(q)

    setup.setStateValidityChecker(valid)
    info = setup.getSpaceInformation()
    info.setStateValidityCheckingResolution(resolution)
    start, goal = space.allocState(), space.allocState()
    for k, j in enumerate(idx):
        start[k], goal[k] = float(qa[j]), float(qb[j])
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(og.RRTConnect(info))
    try:
        if not setup.solve(time_limit) or not setup.haveExactSolutionPath():
            return None
        path = setup.getSolutionPath()
        simplifier = og.PathSimplifier(info)
        simplifier.reduceVertices(path, SHORTCUT_STEPS, SHORTCUT_STEPS // 3)
        simplifier.ropeShortcutPath(path)
        simplifier.reduceVertices(path, SHORTCUT_STEPS, SHORTCUT_STEPS // 3)
        out = []
        for i in range(path.getStateCount()):
            state = path.getState(i)
            full = qa.copy()
            for k, j in enumerate(idx):
                full[j] = state[k]
            out.append(full)
        out[0], out[-1] = qa.copy(), qb.copy()
        return out
    finally:
        del setup, info, space, start, goal
        gc.collect(0)  # no OMPL object outlives its plan (nanobind reports survivors at exit); the youngest
        # generation only: a full collection costs about 50 ms in a loaded process


atexit.register(gc.collect)
