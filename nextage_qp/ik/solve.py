"""The offline solve of :class:`~nextage_qp.ik.qp.QPIK`: IK steps integrated to a tolerance, with restarts.

A descent integrates the QP's steps (``config.dt``) with a collision-safe step (:func:`~nextage_qp.ik.safe_step.
advance`) until every target is within tolerance, the cap, or a stall; seeded random restarts escape local minima;
a relaxation gate tries each start without collision rows first (cheap), keeping its answer where that is clear of
every pair and giving the start up where it misses; a memo answers repeated questions.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Protocol

import mink
import mujoco
import numpy as np

from nextage_qp.ik.collision import ActiveCollisionLimit
from nextage_qp.ik.config import IKConfig
from nextage_qp.ik.kinematic_model import Frame, ObjectPoses, chain_dofs, set_object_poses
from nextage_qp.ik.limits import JointBoxLimit
from nextage_qp.ik.memo import SolveMemo
from nextage_qp.ik.safe_step import advance
from nextage_qp.ik.search import Descent, Search
from nextage_qp.ik.starts import Starts
from nextage_qp.ik.targets import FrameTarget, IKResult, worst_errors

RELAXED_MARGIN = 2.0
"""The relaxation gate of :meth:`QPIK.solve` gives up on a start whose descent without collision rows misses the
targets by more than this many times the accepted errors."""


class DifferentialIK(Protocol):
    """What the offline solve integrates: the differential IK (:class:`~nextage_qp.ik.qp.QPIK`) it is composed with."""

    config: IKConfig
    model: mujoco.MjModel
    configuration: mink.Configuration
    collision: ActiveCollisionLimit | None
    box: JointBoxLimit
    posture: mink.PostureTask
    nb: int
    base_pose: np.ndarray
    mocap: dict[str, int]

    def frame(self, name: str) -> Frame:
        """A body or site of the IK's model."""

    def allowed(self, groups: frozenset[str]) -> np.ndarray:
        """Boolean geom mask of the named collision groups."""

    def full(self, q: np.ndarray) -> np.ndarray:
        """The IK's variables for robot joints ``q``."""

    def velocity(self, targets: Sequence[FrameTarget], dt: float, extra_tasks: Sequence[mink.Task], *,
                 base: bool = False, rows: bool = True) -> np.ndarray:
        """Every IK variable's velocity at the loaded configuration; ``rows=False``: without collision rows."""


class OfflineSolver:
    """An IK's offline solve: descents of its steps to a tolerance, seeded restarts, the relaxation gate, memos.

    Args:
        ik: The differential IK whose steps are integrated (its configuration is the solve's scratch state).
        memo: Remember this many solve results and as many descents without collision rows by their inputs
            (:class:`~nextage_qp.ik.memo.SolveMemo`); 0: none.
    """

    def __init__(self, ik: DifferentialIK, memo: int = 0) -> None:
        self.ik = ik
        self.memo: SolveMemo[IKResult] | None = SolveMemo(memo) if memo > 0 else None
        self.relaxed_memo: SolveMemo[Descent] | None = SolveMemo(memo) if memo > 0 else None
        """Descents without collision rows, remembered by their inputs (the same size as ``memo``)."""

    def solve(
        self,
        targets: Sequence[FrameTarget],
        q0: np.ndarray,
        *,
        max_iters: int | None = None,
        extra_tasks: Sequence[mink.Task] = (),
        object_poses: ObjectPoses | None = None,
        allow: frozenset[str] = frozenset(),
        good_enough: tuple[float, float] | None = None,
        accept: tuple[float, float] | None = None,
        restarts: int | None = None,
    ) -> IKResult:
        """Iterate IK steps of ``config.dt`` from ``q0`` until every target is within tolerance.

        A descent that stalls in a local minimum (or hits the iteration cap) is restarted up to
        ``config.restarts`` times from random in-limit configurations (seeded, so deterministic). An
        unreachable target ends with ``converged=False`` (status ``max_iters`` or ``stalled``) and the best q
        found; no exception. A step that would bring a watched collision pair below its minimum distance is
        halved until it does not.

        **Relaxation gate** (with ``accept`` and collision pairs). Every start (the first, then each restart) gets
        a descent on the relaxed problem without collision rows first, whose steps cost a fraction as much (no
        distance queries, no collision-safe halving). A relaxed descent that misses the targets by more than
        ``RELAXED_MARGIN`` times the accepted errors gives its start up: collision rows only shrink what a descent
        can reach. A restart's relaxed descent that reaches them clear of every watched pair is an answer in itself
        (it meets every constraint the rows keep). One that reaches them only through a collision gives its start up
        too, a trade of reach for time (the collision-aware descent seldom reaches the targets from such a start, at
        a descent of the costly steps each), and the planner's caller tries its next route instead. The first start
        always gets the collision-aware descent when its relaxed one came near, so that answer keeps clear along the
        way from ``q0`` too. When no start comes near, the result is ``q0`` itself (``stalled``).

        Args:
            targets: Frame targets, solved together in one QP per step.
            q0: Start configuration [rad] (one value per robot joint).
            max_iters: Iteration cap per descent (default ``config.max_iters``).
            extra_tasks: Further mink tasks added to every step.
            object_poses: Object name -> (pos, quat wxyz) for collision avoidance.
            allow: Collision groups whose pairs are not avoided (e.g. an object the frames hold).
            good_enough: Position [m] and orientation [rad] errors at which a stalled descent is kept without
                restarts, and at which a descent ends at its first step without 1 % progress (a caller that accepts
                millimetres need not pay for restarts or steps chasing microns).
            accept: Position [m] and orientation [rad] errors the caller accepts as reached; turns on the
                relaxation gate (above).
            restarts: Random restarts of this solve (default ``config.restarts``); 0: the descent from ``q0`` only.

        Raises:
            IKInfeasibleError: A step's QP is infeasible (e.g. ``q0`` far outside the joint limits).
        """
        start = time.perf_counter()
        cfg = self.ik.config
        self._prepare(object_poses, allow)
        key = None
        if self.memo is not None and not extra_tasks:  # a mink task's inputs are not all visible: not remembered
            data = self.ik.configuration.data
            key = self.memo.key(targets, q0, (data.mocap_pos, data.mocap_quat, self.ik.base_pose,
                                              self.ik.posture.target_q, *(good_enough or (None,)),
                                              *(accept or (None,))),
                                (str(max_iters), str(restarts), *sorted(allow)))
            found = self.memo.get(key)
            if found is not None:
                self.ik.configuration.update(self.ik.full(found.q))
                return found._replace(time_s=time.perf_counter() - start)
        frames = [self.ik.frame(t.frame) for t in targets]
        starts = self.starts(frames, q0, restarts)
        cap = max_iters or cfg.max_iters
        search = Search(good_enough)
        if self.ik.collision is not None and accept is not None:
            self._gated_search(search, targets, frames, starts, cap, extra_tasks, accept)
        else:
            for q in starts:
                if search.keep(self._descend(targets, frames, q, cap, extra_tasks, enough=good_enough)):
                    break
        if search.best is None:  # no start came near (the gate): the first start itself, as no descent improved on it
            self.ik.configuration.update(starts[0])
            pos_err, rot_err = worst_errors(targets, [f.pose(self.ik.configuration.data) for f in frames])
            search.best = (pos_err / cfg.pos_tol + rot_err / cfg.rot_tol, starts[0].copy(), pos_err, rot_err, "stalled")
        _, q_best, pos_err, rot_err, status = search.best
        self.ik.configuration.update(q_best)
        result = IKResult(q_best[self.ik.nb :] if self.ik.nb else q_best, status == "converged", pos_err, rot_err,
                          search.iters, status, time.perf_counter() - start)
        if key is not None and self.memo is not None:
            self.memo.put(key, result)
        return result

    def starts(self, frames: Sequence[Frame], q0: np.ndarray, restarts: int | None = None) -> Starts:
        """The starts of a solve for ``frames`` from ``q0``: ``q0``, then ``restarts`` seeded random ones.

        ``restarts`` defaults to ``config.restarts``. Restarts re-draw only the joints that move a target frame; the
        others keep their ``q0`` values (and a mobile robot's base stays where it is: a solve plans the arms).
        """
        moving = np.any([chain_dofs(self.ik.model, f) for f in frames], axis=0)
        moving[: self.ik.nb] = False
        return Starts(self.ik.full(np.array(q0, dtype=float)), moving, self.ik.box.lower[self.ik.nb :],
                       self.ik.box.upper[self.ik.nb :], (self.ik.config.restarts if restarts is None else restarts) + 1,
                       self.ik.config.seed)

    def _prepare(self, object_poses: ObjectPoses | None, allow: frozenset[str]) -> None:
        """Set a solve's allowed collision groups and object poses."""
        if self.ik.collision is not None:
            self.ik.collision.allow(self.ik.allowed(allow))
        if object_poses:
            set_object_poses(self.ik.model, self.ik.configuration.data, object_poses, self.ik.mocap)

    def _gated_search(
        self,
        search: Search,
        targets: Sequence[FrameTarget],
        frames: Sequence[Frame],
        starts: Starts,
        cap: int,
        extra_tasks: Sequence[mink.Task],
        accept: tuple[float, float],
    ) -> None:
        """The relaxation gate's search (see :meth:`solve`), its outcomes kept in ``search``."""
        collision = self.ik.collision
        assert collision is not None
        within, enough = (RELAXED_MARGIN * accept[0], RELAXED_MARGIN * accept[1]), search.good_enough
        for k, q in enumerate(starts):
            relaxed = self._descend(targets, frames, q, cap, extra_tasks, relaxed=True, enough=enough)
            search.iters += relaxed[4]
            if relaxed[2] > within[0] or relaxed[3] > within[1]:
                continue  # out of reach from this start even through collisions
            # The first start's answer comes from the collision-aware descent when it reaches (its path keeps clear
            # too). A restart's relaxed answer through a collision is never one, and its start is given up (see solve).
            if k == 0 and search.keep(self._descend(targets, frames, q, cap, extra_tasks, enough=enough)):
                break
            self.ik.configuration.update(relaxed[1])
            if collision.clear(self.ik.configuration.data) and search.keep((*relaxed[:4], 0, relaxed[5])):
                break

    def _descend(
        self,
        targets: Sequence[FrameTarget],
        frames: Sequence[Frame],
        q0: np.ndarray,
        cap: int,
        extra_tasks: Sequence[mink.Task],
        *,
        relaxed: bool = False,
        enough: tuple[float, float] | None = None,
        rows: bool = True,
    ) -> Descent:
        """One descent from ``q0``.

        ``relaxed``: without collision rows (and without the collision-safe step), remembered; ``rows=False``: the
        descent itself without them. ``enough``: the position [m] and
        orientation [rad] errors the caller is content with (``solve``'s ``good_enough``): once the best errors are
        within them, the descent stalls at its first step without 1 % progress (not ``config.stall_iters``).
        """
        if relaxed and self.ik.collision is not None:
            # A deterministic function of the targets, the start, the posture target and the caps (no collision
            # rows, no object): remembered, as the restarts of solves of the same targets start alike.
            memo, key = self.relaxed_memo, None
            if memo is not None and not extra_tasks:
                key = memo.key(targets, q0, (self.ik.posture.target_q, self.ik.base_pose, *(enough or (None,))),
                               (str(cap),))
                found = memo.get(key)
                if found is not None:
                    return found
            outcome = self._descend(targets, frames, q0, cap, extra_tasks, enough=enough, rows=False)
            if key is not None and memo is not None:
                memo.put(key, outcome)
            return outcome
        cfg, q = self.ik.config, q0.copy()
        self.ik.configuration.update(q)
        best = (np.inf, q.copy(), np.inf, np.inf)
        since_best, iters, window = 0, 0, cfg.stall_iters
        while True:
            pos_err, rot_err = worst_errors(targets, [f.pose(self.ik.configuration.data) for f in frames])
            score = pos_err / cfg.pos_tol + rot_err / cfg.rot_tol
            if score < best[0]:
                since_best = 0 if score < 0.99 * best[0] else since_best
                best = (score, q.copy(), pos_err, rot_err)
                if enough is not None and pos_err <= enough[0] and rot_err <= enough[1]:
                    window = 1
            if pos_err <= cfg.pos_tol and rot_err <= cfg.rot_tol:
                return Descent(*best, iters, "converged")
            if iters >= cap:
                return Descent(*best, iters, "max_iters")
            if since_best >= window:
                return Descent(*best, iters, "stalled")
            dq = self.ik.velocity(targets, cfg.dt, extra_tasks, rows=rows) * cfg.dt
            q_prev, q = q, self._advance(q, dq, rows)
            iters, since_best = iters + 1, since_best + 1
            if q is q_prev:
                # Every halving of the step ran into a collision pair: the next steps would start from the same q
                # and be the same, with no progress, until the cap or the stall test ends the descent. End it now
                # with the same outcome and iteration count.
                ahead = min(cap - iters, window - since_best)
                if ahead > 0:
                    iters, since_best = iters + ahead, since_best + ahead
                return Descent(*best, iters, "max_iters" if iters >= cap else "stalled")

    def _advance(self, q: np.ndarray, dq: np.ndarray, rows: bool = True) -> np.ndarray:
        """Q + dq inside the joint limits, collision-safe with ``rows`` (:func:`~nextage_qp.ik.safe_step.advance`)."""
        collision = self.ik.collision if rows else None
        if collision is None:
            q_new = np.clip(q + dq, self.ik.box.lower, self.ik.box.upper)
            self.ik.configuration.update(q_new)
            return q_new
        return advance(collision, self.ik.configuration, q, dq, self.ik.box.lower, self.ik.box.upper)
