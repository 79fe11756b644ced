"""The robot's cameras: the ``cameras:`` section of a robot file, added to the model with MjSpec.

.. code-block:: yaml

    cameras:
      head_rgbd:                       # a camera named head_rgbd is added to the model
        body: head_link
        pos: [0.088, 0.0, 0.105]       # in the body [m]
        pitch: 0.25                    # looks along the body's +x, pitched down [rad] (and yaw about z)
        fovx: 70                       # horizontal field of view [deg]
        width: 320
        height: 240
        rate_hz: 15
        latency_s: 0.03
        depth_noise: {sigma_m: 0.0012, per_m2: 0.0019, edge_m: 0.01, edge_dropout: 0.5}

A camera looks along MuJoCo's convention (its -z axis forward, +y up). Its intrinsics follow from the width,
height and horizontal field of view (square pixels, principal point at the centre).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from pydantic import Field

from nextage_qp.errors import ConfigError
from nextage_qp.io.schema import YamlModel


class DepthNoise(YamlModel):
    """Depth noise of a range camera: axial sigma ``sigma_m + per_m2 * z^2`` and missing pixels at depth edges."""

    sigma_m: float = Field(default=0.0012, ge=0, le=0.1, allow_inf_nan=False, description="Axial sigma at 0 m [m].")
    per_m2: float = Field(default=0.0019, ge=0, le=0.1, allow_inf_nan=False,
                          description="Growth of the axial sigma with the distance squared [1/m].")
    edge_m: float = Field(default=0.01, gt=0, le=1.0, allow_inf_nan=False,
                          description="Depth step between neighbouring pixels that makes an edge [m].")
    edge_dropout: float = Field(default=0.5, ge=0, le=1.0, allow_inf_nan=False,
                                description="Probability [1] that an edge pixel has no depth.")


class CameraFile(YamlModel):
    """One camera of a robot file (see the module docstring)."""

    body: str = Field(min_length=1, description="Body the camera is mounted on.")
    pos: tuple[float, float, float] = Field(default=(0.0, 0.0, 0.0), description="Position in the body [m].")
    pitch: float = Field(default=0.0, ge=-1.6, le=1.6, description="Pitch down from the body's +x [rad].")
    yaw: float = Field(default=0.0, ge=-3.2, le=3.2, description="Yaw about the body's z [rad].")
    fovx: float = Field(default=80.0, gt=5.0, lt=170.0, description="Horizontal field of view [deg].")
    width: int = Field(default=320, ge=16, le=4096, description="Image width [px].")
    height: int = Field(default=240, ge=16, le=4096, description="Image height [px].")
    rate_hz: float = Field(default=15.0, gt=0, le=120.0, allow_inf_nan=False, description="Frame rate [Hz].")
    latency_s: float = Field(default=0.03, ge=0, le=1.0, allow_inf_nan=False,
                             description="Time from exposure to the estimate reaching the controller [s].")
    depth_noise: DepthNoise = Field(
        default_factory=DepthNoise, description="Noise of the rendered depth: an axial sigma growing with the "
                                                "distance squared, and missing pixels at depth edges.")

    @property
    def fovy(self) -> float:
        """Vertical field of view [deg] (MuJoCo's ``fovy``)."""
        half = math.radians(self.fovx) / 2.0
        return math.degrees(2.0 * math.atan(math.tan(half) * self.height / self.width))

    @property
    def intrinsics(self) -> np.ndarray:
        """The 3x3 pinhole matrix K [px] (image x right, y down)."""
        f = self.width / 2.0 / math.tan(math.radians(self.fovx) / 2.0)
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0], [0.0, 0.0, 1.0]])

    def rot(self) -> np.ndarray:
        """The camera's rotation in its body (columns: its x right, y up, z backwards; it looks along -z)."""
        cp, sp, cy, sy = math.cos(self.pitch), math.sin(self.pitch), math.cos(self.yaw), math.sin(self.yaw)
        forward = np.array([cy * cp, sy * cp, -sp])
        up = np.array([cy * sp, sy * sp, cp])
        return np.column_stack([np.cross(up, -forward), up, -forward])

    def quat(self) -> list[float]:
        """The camera's orientation in its body (w, x, y, z), MuJoCo's convention: :meth:`rot` as a quaternion."""
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, self.rot().reshape(9))
        return q.tolist()


def add_cameras(spec: mujoco.MjSpec, cameras: dict[str, CameraFile], source: str) -> None:
    """Add each camera to ``spec``.

    Raises:
        ConfigError: A camera names a body the model lacks, or a camera of that name exists already.
    """
    bodies = {b.name for b in spec.bodies if b.name}
    existing = {c.name for c in spec.cameras}
    for name, cam in cameras.items():
        if cam.body not in bodies:
            raise ConfigError(f"{source}: cameras.{name}.body: {cam.body!r} is not a body of the model; "
                              f"bodies: {', '.join(sorted(bodies))}")
        if name in existing:
            raise ConfigError(f"{source}: cameras.{name}: the model has a camera of that name already")
        body = spec.body(cam.body)
        body.add_camera(name=name, pos=list(cam.pos), quat=cam.quat(), fovy=cam.fovy,
                        resolution=[cam.width, cam.height])
