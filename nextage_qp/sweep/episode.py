"""One sweep episode: the base config with the episode's overrides, run exactly as ``nextage-qp run --set`` runs it.

:func:`run_episode` never raises: whatever happens (a failed task, a refused scene, an exception, the wall-time
limit) comes back as an :class:`Episode` record with a status and a reason, so a sweep drops nothing.
"""

from __future__ import annotations

import os
import socket
import time
import traceback
from dataclasses import asdict, dataclass, field
from typing import Any

from nextage_qp.errors import ConfigError, NextageQPError, one_line

STATUSES = ("success", "failed", "refused", "error", "lost")
"""``success``/``failed``: the task ran and met / missed its criteria; ``refused``: the run rejected its scene
before moving (exit 2); ``error``: an exception, a crash or the wall-time limit stopped the episode; ``lost``: the
process running it died or was killed (out of memory, a signal, a Ray worker lost): the machine's failure, not the
task's, so the sweep runs it again once, and ``--resume`` runs it again, and it counts in no rate."""

UNRATED = ("refused", "lost")
"""Statuses that count in no success rate: a scene refused before moving, an episode whose process was lost."""

TIMING_KEYS = ("wall_time_s", "real_time_factor", "physics_share", "planning_time_s")
"""Result fields that measure the machine, not the episode (left out when episodes are compared)."""


@dataclass(frozen=True)
class EpisodeTask:
    """What a worker needs to run one episode (plain data, picklable).

    Attributes:
        index: Episode number in its sweep.
        base: Path of the task config.
        overrides: ``--set`` strings applied to it, the run seed among them.
        params: The drawn parameters (key -> value), recorded with the result.
        seed: The episode's run seed.
        wall_limit: Wall time [s] after which the episode stops and fails.
    """

    index: int
    base: str
    overrides: tuple[str, ...]
    params: dict[str, Any]
    seed: int
    wall_limit: float


@dataclass
class Episode:
    """The record of one episode, one line of ``episodes.jsonl``.

    Attributes:
        index: Episode number.
        seed: Run seed.
        params: Drawn parameters.
        overrides: The ``--set`` strings that reproduce it with ``nextage-qp run``.
        status: One of :data:`STATUSES`.
        reason: Why it is not a success (None for a success).
        failed_phase: Name of the phase that failed, if one did.
        failed_criteria: Success criteria that did not hold.
        result: The full ``nextage-qp run --json`` result (None when the run never started).
        wall_time_s: Wall time of the episode in its worker [s].
        worker: ``host:pid`` that ran it.
        attempts: How many times it was started (more than one: an earlier attempt was ``lost``).
    """

    index: int
    seed: int
    params: dict[str, Any]
    overrides: list[str]
    status: str
    reason: str | None = None
    failed_phase: str | None = None
    failed_criteria: list[str] = field(default_factory=list)
    result: dict[str, Any] | None = None
    wall_time_s: float = 0.0
    worker: str = ""
    attempts: int = 1

    def to_json(self) -> dict[str, Any]:
        """A plain dict for JSON."""
        return asdict(self)

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> Episode:
        """Inverse of :meth:`to_json`."""
        return cls(**doc)

    def comparable(self) -> dict[str, Any]:
        """The record without machine-dependent fields (wall times, worker), for determinism checks."""
        doc = self.to_json()
        for key in ("wall_time_s", "worker", "attempts"):
            doc.pop(key)
        if doc["result"] is not None:
            doc["result"] = {k: v for k, v in doc["result"].items() if k not in TIMING_KEYS}
        return doc


class WallTimeExceeded(NextageQPError):
    """An episode ran longer than its sweep's wall-time limit."""


def run_episode(task: EpisodeTask) -> Episode:
    """Run one episode in this process and return its record (never raises)."""
    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.runner import Runner
    from nextage_qp.native.mj_warnings import capture_mujoco_warnings

    capture_mujoco_warnings()  # in a worker process: MuJoCo's own prints would interleave with the progress

    start = time.perf_counter()
    record = Episode(task.index, task.seed, dict(task.params), list(task.overrides), status="error",
                     worker=f"{socket.gethostname()}:{os.getpid()}")
    try:
        cfg = load_config(task.base, list(task.overrides))
        runner = Runner(cfg, task.base)
        deadline = start + task.wall_limit
        stopped = []

        def guard(r: Any, phase: Any) -> None:
            if time.perf_counter() > deadline:
                stopped.append(True)
                raise WallTimeExceeded(f"episode exceeded its wall-time limit of {task.wall_limit:g} s "
                                       f"at t={r.sim.time:.2f} s of simulated time")

        result = runner.run(guard)
        record.result = result.as_dict()
        record.failed_criteria = result.failed_criteria
        record.failed_phase = result.failed_phase
        if result.success:
            record.status = "success"
        else:
            record.status = "error" if stopped else "failed"
            record.reason = result.error or result.unmet_criteria()
    except ConfigError as exc:
        record.status, record.reason = "refused", one_line(exc)
    except Exception as exc:
        last = traceback.extract_tb(exc.__traceback__)[-1]
        record.reason = f"{type(exc).__name__}: {exc} (at {os.path.basename(last.filename)}:{last.lineno})"
    record.wall_time_s = time.perf_counter() - start
    return record


def failed_episode(task: EpisodeTask, reason: str, wall_time_s: float, worker: str = "", *,
                   lost: bool = False) -> Episode:
    """The record of an episode that did not come back from its worker.

    ``lost``: its process died or was killed (status ``lost``, run again); else it was stopped for taking too long or
    failed inside the worker (status ``error``).
    """
    return Episode(task.index, task.seed, dict(task.params), list(task.overrides), status="lost" if lost else "error",
                   reason=reason, wall_time_s=wall_time_s, worker=worker)
