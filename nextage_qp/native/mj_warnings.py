"""MuJoCo's warnings, kept for the simulation's one-line errors instead of printed and logged to a file.

By default MuJoCo prints each warning on stdout and appends it to ``MUJOCO_LOG.TXT`` in the working directory.
:class:`~nextage_qp.loop.simulation.Simulation` detects the states MuJoCo warns about from its warning counters and
raises one :class:`~nextage_qp.errors.SimulationError` line that quotes the first warning of the run.
"""

from __future__ import annotations

import mujoco

MUJOCO_WARNINGS: list[str] = []
"""MuJoCo's warnings since the last :meth:`Simulation.reset`, once :func:`capture_mujoco_warnings` is installed."""


def capture_mujoco_warnings() -> None:
    """Keep MuJoCo's warnings in :data:`MUJOCO_WARNINGS` instead of printing them and writing MUJOCO_LOG.TXT.

    The simulation detects the states they warn about from MuJoCo's warning counters and fails with one line
    that quotes the first warning of the run; the command line and the sweep workers install this so nothing else is
    printed. Idempotent.
    """
    def keep(message: str) -> None:
        if len(MUJOCO_WARNINGS) < 16:
            MUJOCO_WARNINGS.append(message)

    mujoco.set_mju_user_warning(keep)
