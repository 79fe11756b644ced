"""The Python API: what the command line does, as a few functions and small typed records.

.. code-block:: python

    import nextage_qp as nq

    task = nq.load_task("configs/push_cube.yaml", overrides=["scene.poses.cube.yaw=0.3"])
    result = task.run(on_tick=lambda tick: None)       # a fresh simulation per run
    print(result.success, result.object_error_xy_m, result.phases[0]["status"])

    summary = nq.run_sweep("configs/sweeps/push_cube.yaml", episodes=20, workers=2)
    print(summary["success_rate"], summary["success_rate_ci95"])

    robot = nq.load_robot("nextage_mobile")            # a robot file on an empty floor
    nq.register_phase(MySpec, MyPhase)                 # a phase kind of your own, usable from YAML

Every function raises :class:`~nextage_qp.errors.ConfigError` (with the one-line message the CLI prints) for bad
input, before anything runs.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nextage_qp.errors import ConfigError
from nextage_qp.manipulation import metrics
from nextage_qp.manipulation.config import ManipulationConfig, load_config
from nextage_qp.manipulation.phases import Phase, Spec, register, unregister
from nextage_qp.robots.model import Robot

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner

__all__ = ["RunResult", "Task", "Tick", "load_robot", "load_task", "register_phase", "run_sweep", "run_task",
           "unregister_phase"]


@dataclass(frozen=True)
class Tick:
    """What an ``on_tick`` hook sees after every control tick.

    Attributes:
        t: Simulated time [s].
        phase: The running phase's name (None while the run settles after its last phase).
        runner: The run itself: ``runner.sim`` (MuJoCo's ``data``, the measurement, the recorder),
            ``runner.servo`` (the commanded joints), ``runner.view`` (what the phases see).
    """

    t: float
    phase: str | None
    runner: Runner


@dataclass(frozen=True)
class RunResult(metrics.RunResult):
    """The outcome of one run, and the finished run itself.

    The record ``nextage-qp run --json`` prints is :attr:`record`; its typed fields are ``success``,
    ``object_error_xy_m``, ``object_yaw_error_rad``, ``failed_criteria``, ``failed_phase``, ``error`` (which phase
    failed and why, or None), ``phases`` (per phase: name, kind, status, start and duration [s] and the phase's own
    figures), ``sim_time_s`` and ``wall_time_s`` [s].

    Attributes:
        record: The whole result record.
        runner: The finished run (its recorder holds every tick's signals: ``runner.sim.recorder.arrays()``).
    """

    runner: Runner | None = None


class Task:
    """A validated task config, ready to run; each :meth:`run` builds a fresh simulation.

    Args:
        config: The validated config (:func:`load_task` makes one from a file).
        source: Where it came from (for messages; relative paths in it are already resolved).
    """

    def __init__(self, config: ManipulationConfig, source: str = "<config>") -> None:
        self.config, self.source = config, source

    @property
    def name(self) -> str:
        """The config's ``task`` name."""
        return self.config.task

    def runner(self) -> Runner:
        """A new run of the task, not started (for a caller that drives it tick by tick or adds hooks)."""
        from nextage_qp.manipulation.runner import Runner

        return Runner(self.config, self.source)

    def run(self, *, on_tick: Callable[[Tick], None] | None = None) -> RunResult:
        """Run every phase, then settle; ``on_tick`` is called after every control tick.

        A task that fails (a phase gives up or times out, a criterion does not hold) returns a result with
        ``success`` False and ``error`` saying which phase and why; it does not raise.

        Raises:
            ConfigError: The config names something the scene does not have, or a target that cannot be done at all
                (refused before anything moves).
        """
        runner = self.runner()
        hook = None
        if on_tick is not None:
            def hook(r: Runner, phase: Phase | None) -> None:
                on_tick(Tick(r.sim.time, None if phase is None else phase.name, r))

        return RunResult(runner.run(hook).record, runner)


def load_task(path: str | Path, *, overrides: Sequence[str] = ()) -> Task:
    """Load and validate a task config: a path, or a bundled name (``push_cube``, ``dock_dumbbell``, ...).

    ``overrides`` are ``KEY=VALUE`` strings, as ``nextage-qp run --set`` takes them
    (``"scene.poses.cube.pos=[0.35, 0.02, 0.91]"``).

    Raises:
        ConfigError: The file is missing or invalid, or an override names a key the config does not have.
    """
    return Task(load_config(_path(path, "path"), _overrides(overrides)), str(path))


def _path(value: Any, what: str) -> str | Path:
    """``value`` if it is a path (a str or os.PathLike); a ConfigError naming ``what`` otherwise."""
    if isinstance(value, str) and value.strip():
        return value
    if isinstance(value, os.PathLike) and os.fspath(value):
        return Path(value)
    raise ConfigError(f"{what}: {value!r} is not a file path or bundled name (give a str or pathlib.Path)")


def _overrides(overrides: Sequence[str]) -> list[str]:
    """``overrides`` as a list of ``KEY=VALUE`` strings (a lone string is one override, not its characters)."""
    items = [overrides] if isinstance(overrides, str) else list(overrides)
    bad = [o for o in items if not isinstance(o, str)]
    if bad:
        raise ConfigError(f"overrides: {bad[0]!r} is not a 'KEY=VALUE' string")
    return items


def run_task(path: str | Path, *, overrides: Sequence[str] = (), on_tick: Callable[[Tick], None] | None = None
             ) -> RunResult:
    """:func:`load_task`, then :meth:`Task.run`."""
    if on_tick is not None and not callable(on_tick):
        raise ConfigError(f"on_tick: {on_tick!r} is not callable (give a function of one Tick, or None)")
    return load_task(path, overrides=overrides).run(on_tick=on_tick)


def run_sweep(path: str | Path, episodes: int, *, seed: int = 0, workers: int | None = None,
              out: str | Path | None = None, overrides: Sequence[str] = ()) -> dict[str, Any]:
    """Run ``episodes`` randomised episodes of a sweep file (``nextage-qp sweep``) and return its summary.

    The workers are spawned processes, which import the calling script again: call this under
    ``if __name__ == "__main__":``.

    Args:
        path: The sweep file.
        episodes: How many episodes (indices 0 to ``episodes`` - 1).
        seed: The sweep's seed: the same seed gives the same scenes.
        workers: Processes (default: one per core).
        out: Folder the episode records and ``summary.json`` are kept in (default: ``runs/sweeps/NAME-seedS``).
        overrides: ``KEY=VALUE`` overrides of the base config.

    Returns:
        The summary ``nextage-qp sweep --json`` writes: ``success_rate``, ``success_rate_ci95``, error quantiles,
        failures by phase and criterion, success per parameter bin, and a replay command per failure.

    Raises:
        ConfigError: The sweep file or an override is invalid.
    """
    from nextage_qp.sweep.run import plan
    from nextage_qp.sweep.run import run_sweep as run
    from nextage_qp.sweep.spec import SweepSpec
    from nextage_qp.sweep.store import SweepStore, default_folder
    from nextage_qp.sweep.summary import write_summary

    if isinstance(episodes, bool) or not isinstance(episodes, int) or not 1 <= episodes <= 1_000_000:
        raise ConfigError(f"episodes: {episodes!r} must be a whole number from 1 to 1000000")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"workers: {workers!r} must be a whole number >= 1, or None (one per core)")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise ConfigError(f"seed: {seed!r} must be a whole number in [0, 2**32)")
    spec = SweepSpec(_path(path, "path"), _overrides(overrides))
    folder = Path(_path(out, "out")) if out is not None else default_folder(spec, seed)
    store = SweepStore(folder, spec, seed, resume=False)
    tasks = plan(spec, seed, range(episodes))
    start = time.monotonic()
    try:
        done = run(tasks, store=store, workers=max(1, min(workers or os.cpu_count() or 1, len(tasks))))
    finally:
        store.close()
    return write_summary(folder, spec, seed, done, session_episodes=len(done), session_wall_s=time.monotonic() - start)


def load_robot(ref: str | Path | None = None, *, scene: str | Path = "scene") -> Robot:
    """A robot file (bundled name such as ``nextage``, ``yumi``, ``nextage_mobile``, or a path) in a scene.

    Raises:
        ConfigError: The robot file or the scene is invalid, or they do not compile together.
    """
    return Robot.from_scene(_path(scene, "scene"), robot=None if ref is None else _path(ref, "ref"))


def register_phase(spec: type[Spec], phase: type[Phase]) -> None:
    """Add a phase kind that task configs loaded afterwards may use (a kind registered again is replaced).

    ``spec`` is a :class:`~nextage_qp.manipulation.phases.base.Spec` with a ``kind`` literal, ``phase`` a
    :class:`~nextage_qp.manipulation.phases.base.Phase`.
    """
    register(spec, phase)


def unregister_phase(kind: str) -> None:
    """Remove a phase kind added with :func:`register_phase`."""
    unregister(kind)
