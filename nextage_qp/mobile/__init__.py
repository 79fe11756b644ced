"""Mobile bases: wheeled-base kinematics, odometry, and the base's rows in the IK QP."""

from nextage_qp.mobile.drive_models import Bicycle, DiffDrive, Pose2, Twist, body_twist, integrate, relative

__all__ = ["Bicycle", "DiffDrive", "Pose2", "Twist", "body_twist", "integrate", "relative"]
