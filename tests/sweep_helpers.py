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
