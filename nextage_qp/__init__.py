"""nextage_qp: QP task-space control of dual-arm robots in MuJoCo, born on the Kawada Nextage.

The Python API (:mod:`nextage_qp.api`): :func:`load_task`, :func:`run_task`, :class:`Task`, :class:`RunResult`,
:func:`run_sweep`, :func:`load_robot`, :func:`register_phase`; the errors every function raises on bad input.
"""

from typing import Any

from nextage_qp.errors import (
    ConfigError,
    IKError,
    NextageQPError,
    PhaseError,
    SimulationError,
    TrajectoryError,
    UnknownFrameError,
    UnknownJointError,
    UnknownNameError,
)
from nextage_qp.robot import Robot
from nextage_qp.scene import SceneOverrides

_API = ("RunResult", "Task", "Tick", "load_robot", "load_task", "register_phase", "run_sweep", "run_task",
        "unregister_phase")


def __getattr__(name: str) -> Any:
    """The API's names, imported when first used (``import nextage_qp`` stays light)."""
    if name in _API:
        from nextage_qp import api

        return getattr(api, name)
    raise AttributeError(f"module 'nextage_qp' has no attribute {name!r}")


__all__ = [
    "ConfigError",
    "IKError",
    "NextageQPError",
    "PhaseError",
    "Robot",
    "SceneOverrides",
    "SimulationError",
    "TrajectoryError",
    "UnknownFrameError",
    "UnknownJointError",
    "UnknownNameError",
    *_API,
]

__version__ = "0.1.0"
