"""Episode functions for the sweep tests, importable by spawned workers (they live at module level)."""

import os
import time

from nextage_qp.sweep.episode import run_episode


def faulty_episode(task):
    """Episode 1 raises, episode 2 hangs past any limit, episode 3 kills its worker; the rest run for real."""
    if task.index == 1:
        raise RuntimeError("boom in episode 1")
    if task.index == 2:
        time.sleep(600)
    if task.index == 3:
        os._exit(3)
    return run_episode(task)


def killed_once_episode(task):
    """Episode 1's first attempt is killed with SIGKILL mid-episode (a marker file in $NQ_KILL_MARKS remembers it)."""
    import signal
    import threading
    from pathlib import Path

    mark = Path(os.environ["NQ_KILL_MARKS"]) / f"{task.index}.killed"
    if task.index == 1 and not mark.exists():
        mark.touch()
        threading.Timer(0.5, os.kill, args=(os.getpid(), signal.SIGKILL)).start()
    return run_episode(task)


def instant_success(task):
    """A success record without running anything (for the sweep's bookkeeping tests)."""
    from nextage_qp.sweep.episode import Episode

    return Episode(task.index, task.seed, dict(task.params), list(task.overrides), status="success")
