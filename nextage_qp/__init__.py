"""nextage_qp: QP task-space control of dual-arm robots in MuJoCo, born on the Kawada Nextage."""

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
]

__version__ = "0.1.0"
