"""Inverse kinematics: QP differential IK on mink (:class:`QPIK`) and the baselines it is compared with."""

from nextage_qp.ik.collision import ActiveCollisionLimit
from nextage_qp.ik.config import CollisionPairConfig, IKConfig
from nextage_qp.ik.kinematic_model import kinematic_model
from nextage_qp.ik.limits import JointBoxLimit
from nextage_qp.ik.qp import QPIK
from nextage_qp.ik.targets import FrameTarget, IKInfeasibleError, IKResult, RelativeTarget, target_errors

__all__ = [
    "QPIK",
    "ActiveCollisionLimit",
    "CollisionPairConfig",
    "FrameTarget",
    "IKConfig",
    "IKInfeasibleError",
    "IKResult",
    "JointBoxLimit",
    "RelativeTarget",
    "kinematic_model",
    "target_errors",
]
