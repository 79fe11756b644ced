"""nextage_qp: QP task-space control of dual-arm robots in MuJoCo, born on the Kawada Nextage.

The Python API (:mod:`nextage_qp.api`): :func:`load_task`, :func:`run_task`, :class:`Task`, :class:`RunResult`,
:func:`run_sweep`, :func:`load_robot`, :func:`register_phase`; the errors every function raises on bad input.
"""

import os
import sys
from typing import Any

try:  # MuJoCo loads the OpenGL platform MUJOCO_GL names when it is imported
    import mujoco  # noqa: F401
except (ImportError, RuntimeError, AttributeError) as _exc:  # pragma: no cover - a machine without that platform
    _gl = os.environ.get("MUJOCO_GL")
    _message = (f"MuJoCo cannot load with MUJOCO_GL={_gl!r} ({' '.join(str(_exc).split())}); valid: egl (Debian "
                "libegl1 libegl-mesa0 libgl1-mesa-dri), osmesa (libosmesa6), glfw (a display), or unset"
                if _gl else f"MuJoCo cannot load: {' '.join(str(_exc).split())}")
    if os.path.basename(sys.argv[0]) in ("nextage-qp", "-m", "cli.py"):  # the command line: one line, exit 2
        print(f"nextage-qp: error: {_message}", file=sys.stderr)
        raise SystemExit(2) from None
    raise ImportError(_message) from None

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
from nextage_qp.robots.model import Robot
from nextage_qp.scene.files import SceneOverrides

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
