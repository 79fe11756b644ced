"""Where episodes run: a local process pool (pebble, spawn start method) or a Ray cluster.

Both take the same list of :class:`~nextage_qp.sweep.episode.EpisodeTask` and call ``on_done`` with one
:class:`~nextage_qp.sweep.episode.Episode` per task, in the order they finish. Whatever happens to a task, it
comes back: a worker that dies, a task that outlives its wall-time limit (plus ``GRACE_S``, then the worker is
killed) or an exception in the worker becomes a failed episode with its reason. Every worker builds its own
MuJoCo model per episode, runs with one BLAS/OpenMP thread and renders nothing.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Sequence
from typing import Any

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.sweep.episode import Episode, EpisodeTask, failed_episode, run_episode

EpisodeFn = Callable[[EpisodeTask], Episode]
OnDone = Callable[[Episode], None]

GRACE_S = 30.0
"""Time past an episode's own wall-time check after which its worker is killed [s] (a hang in C code)."""

THREAD_ENV = {var: "1" for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                   "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")}
"""Environment of every worker: one thread per numerical library, so W workers use W cores."""


def _init_worker() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle: it stops the pool


def local_pool(workers: int) -> Any:
    """A pool of ``workers`` spawned processes, each with one numerical thread and ignoring Ctrl-C."""
    import pebble

    os.environ.update({k: os.environ.get(k, v) for k, v in THREAD_ENV.items()})  # inherited by spawned workers
    return pebble.ProcessPool(max_workers=workers, context=multiprocessing.get_context("spawn"),
                              initializer=_init_worker)


def run_local(tasks: Sequence[EpisodeTask], workers: int, on_done: OnDone, *, episode_fn: EpisodeFn = run_episode,
              grace: float = GRACE_S, pool: Any = None) -> None:
    """Run ``tasks`` on ``workers`` spawned processes; on Ctrl-C the workers are stopped and the error re-raised.

    ``pool`` (from :func:`local_pool`) reuses running workers across calls; it is left open, except on an error.
    """
    import pebble

    own = pool is None
    if own:
        pool = local_pool(workers)
    try:
        futures: dict[concurrent.futures.Future[Episode], EpisodeTask] = {
            pool.schedule(episode_fn, args=(t,), timeout=t.wall_limit + grace): t for t in tasks
        }
        for future in concurrent.futures.as_completed(futures):
            task = futures[future]
            try:
                episode = future.result()
            except concurrent.futures.TimeoutError:
                episode = failed_episode(task, f"killed: no answer {task.wall_limit + grace:g} s after it started "
                                         f"(wall-time limit {task.wall_limit:g} s + {grace:g} s)",
                                         task.wall_limit + grace)
            except pebble.ProcessExpired as exc:
                episode = failed_episode(task, f"worker process died (exit code {exc.exitcode})", 0.0, lost=True)
            except Exception as exc:
                episode = failed_episode(task, f"{type(exc).__name__}: {exc}", 0.0)
            on_done(episode)
    except BaseException:
        pool.stop()
        pool.join()
        raise
    if own:
        pool.close()
        pool.join()


def ray_init(workers: int | None, address: str | None = None) -> bool:
    """Start or join Ray for a run; returns whether this call started it (then the caller shuts it down).

    Raises:
        ConfigError: Ray is not installed or the cluster cannot be reached.
    """
    try:
        import ray
    except ImportError:
        raise ConfigError('--backend ray needs Ray: pip install -e ".[ray]"') from None
    if ray.is_initialized():
        return False
    address = address or os.environ.get("RAY_ADDRESS") or None
    try:
        ray.init(address=address, num_cpus=None if address else workers, include_dashboard=False,
                 log_to_driver=False, runtime_env={"env_vars": dict(THREAD_ENV)})
    except Exception as exc:
        raise ConfigError(f"--backend ray: cannot start or reach Ray at {address or 'a local instance'}: "
                          f"{one_line(exc)}") from None
    return True


def run_ray(tasks: Sequence[EpisodeTask], workers: int | None, on_done: OnDone, *, address: str | None = None,
            episode_fn: EpisodeFn = run_episode, grace: float = GRACE_S) -> None:
    """Run ``tasks`` as Ray tasks (one CPU each), at most ``workers`` at a time (default: the cluster's CPUs).

    ``address`` (or ``RAY_ADDRESS``) connects to a running cluster; without either a local Ray instance is
    started for the sweep and shut down after it.

    Raises:
        ConfigError: Ray is not installed or the cluster cannot be reached.
    """
    started = ray_init(workers, address)
    import ray
    from ray.exceptions import GetTimeoutError, RayError

    remote = ray.remote(num_cpus=1, max_retries=0)(episode_fn)
    capacity = max(1, workers or int(ray.cluster_resources().get("CPU", 1)))
    pending: list[EpisodeTask] = list(tasks)
    running: dict[Any, tuple[EpisodeTask, float]] = {}  # Ray object ref -> (task, start time)
    try:
        while pending or running:
            while pending and len(running) < capacity:
                task = pending.pop(0)
                running[remote.remote(task)] = (task, time.monotonic())
            ready, _ = ray.wait(list(running), num_returns=1, timeout=1.0)
            for ref in ready:
                task, t0 = running.pop(ref)
                try:
                    episode = ray.get(ref, timeout=60)
                except (RayError, GetTimeoutError) as exc:
                    episode = failed_episode(task, f"Ray task failed: {type(exc).__name__}: "
                                             f"{one_line(exc)[:300]}", time.monotonic() - t0, lost=True)
                on_done(episode)
            now = time.monotonic()
            for ref, (task, t0) in list(running.items()):
                if now - t0 > task.wall_limit + grace:
                    ray.cancel(ref, force=True)
                    running.pop(ref)
                    on_done(failed_episode(task, f"killed: no answer {task.wall_limit + grace:g} s after it started "
                                           f"(wall-time limit {task.wall_limit:g} s + {grace:g} s)", now - t0))
    except BaseException:
        for ref in running:
            ray.cancel(ref, force=True)
        raise
    finally:
        if started:
            ray.shutdown()
