"""Plan and run a sweep: episode tasks from (seed, index), a backend to run them, a store that keeps them."""

from __future__ import annotations

import dataclasses
import shlex
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from nextage_qp.sweep.backends import GRACE_S, run_local, run_ray
from nextage_qp.sweep.episode import Episode, EpisodeTask, run_episode
from nextage_qp.sweep.spec import SweepSpec
from nextage_qp.sweep.store import SweepStore


def plan(spec: SweepSpec, seed: int, indices: Iterable[int]) -> list[EpisodeTask]:
    """One task per episode index; each task depends on (spec, seed, index) alone."""
    tasks = []
    for i in indices:
        params, run_seed = spec.draw(seed, i)
        tasks.append(EpisodeTask(i, str(spec.base_path), tuple(spec.overrides(params, run_seed)), params, run_seed,
                                 spec.wall_limit))
    return tasks


def run_sweep(
    tasks: Sequence[EpisodeTask],
    *,
    store: SweepStore | None,
    workers: int,
    backend: str = "local",
    ray_address: str | None = None,
    on_episode: Callable[[Episode], None] | None = None,
    episode_fn: Callable[[EpisodeTask], Episode] = run_episode,
    grace: float = GRACE_S,
    pool: Any = None,
) -> list[Episode]:
    """Run every task not already in ``store``; each finished episode is stored before ``on_episode`` sees it.

    An episode whose process died or was killed (status ``lost``: the machine's failure, not the task's) runs once
    more, after the others; its record then counts two ``attempts``. ``pool``
    (:func:`~nextage_qp.sweep.backends.local_pool`) keeps the local workers across calls.

    Returns:
        The episodes of ``tasks`` (resumed ones included), in index order.
    """
    done = dict(store.done) if store is not None else {}
    todo = [t for t in tasks if t.index not in done]
    tried = {i: e.attempts for i, e in store.lost.items()} if store is not None else {}  # lost before a --resume

    def finished(episode: Episode) -> None:
        if episode.index in tried:
            episode = dataclasses.replace(episode, attempts=tried[episode.index] + episode.attempts)
        done[episode.index] = episode
        if store is not None:
            store.add(episode)
        if on_episode is not None:
            on_episode(episode)

    def run(batch: Sequence[EpisodeTask], on_done: Callable[[Episode], None]) -> None:
        if backend == "ray":
            run_ray(batch, workers, on_done, address=ray_address, episode_fn=episode_fn, grace=grace)
        else:
            run_local(batch, workers, on_done, episode_fn=episode_fn, grace=grace, pool=pool)

    if todo:
        run(todo, finished)
    lost = [t for t in todo if t.index in done and done[t.index].status == "lost"]
    if lost:  # once more: a worker that died is the machine's failure, not the episode's
        tried.update({t.index: done[t.index].attempts for t in lost})
        run(lost, finished)
    return [done[t.index] for t in tasks if t.index in done]


def replay_commands(spec: SweepSpec, seed: int, episode: Episode, cwd: Path | None = None) -> dict[str, str]:
    """Two commands that re-run one episode alone: through the sweep, and as ``nextage-qp run --set ...``."""
    sweep = _shown(spec.path, cwd)
    base = _shown(spec.base_path, cwd)
    sets = " ".join(f"--set {shlex.quote(o)}" for o in episode.overrides)
    extra = "".join(f" --set {shlex.quote(o)}" for o in spec.extra)
    return {"sweep": f"nextage-qp sweep {shlex.quote(sweep)} --seed {seed} --only {episode.index}{extra}",
            "run": f"nextage-qp run {shlex.quote(base)} {sets}"}


def _shown(path: Path, cwd: Path | None) -> str:
    here = (cwd or Path.cwd()).resolve()
    try:
        return str(path.resolve().relative_to(here))
    except ValueError:
        return str(path)
