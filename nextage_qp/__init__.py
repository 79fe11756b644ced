"""nextage_qp: QP task-space control of the Kawada Nextage dual-arm robot in MuJoCo."""

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
from nextage_qp.nextage import JOINT_NAMES
from nextage_qp.robot import Robot
from nextage_qp.scene import SceneOverrides

__all__ = [
    "JOINT_NAMES",
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
