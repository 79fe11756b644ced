"""nextage_qp: QP task-space control of dual-arm robots in MuJoCo, born on the Kawada Nextage.

The Python API (:mod:`nextage_qp.api`): :func:`load_task`, :func:`run_task`, :class:`Task`, :class:`RunResult`,
:func:`run_sweep`, :func:`load_robot`, :func:`register_phase`; the errors every function raises on bad input.
"""

import importlib
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

_API = ("RunResult", "Task", "Tick", "load_robot", "load_task", "register_phase", "run_sweep", "run_task",
        "unregister_phase")


_LAZY = {"Robot": "nextage_qp.robots.model", "SceneOverrides": "nextage_qp.scene.files",
         **{name: "nextage_qp.api" for name in _API}}
"""Names imported when first used (``import nextage_qp`` loads neither MuJoCo nor numpy)."""


def __getattr__(name: str) -> Any:
    """The API's names, imported when first used; MuJoCo's failure to load is one :class:`ImportError` line."""
    if name in _LAZY:
        from nextage_qp.native.loading import require_mujoco

        try:
            require_mujoco()
        except ConfigError as exc:
            raise ImportError(str(exc)) from None
        return getattr(importlib.import_module(_LAZY[name]), name)
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
