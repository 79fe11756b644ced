"""MuJoCo imported on demand, with one clear line when the OpenGL platform ``MUJOCO_GL`` names cannot load."""

from __future__ import annotations

import os

from nextage_qp.errors import ConfigError, one_line


def require_mujoco() -> None:
    """Import MuJoCo (it loads the OpenGL platform ``MUJOCO_GL`` names when it is imported).

    Raises:
        ConfigError: MuJoCo cannot load; the message names ``MUJOCO_GL`` and its valid values.
    """
    try:
        import mujoco  # noqa: F401
    except (ImportError, RuntimeError, AttributeError) as exc:  # pragma: no cover - a machine without that platform
        gl = os.environ.get("MUJOCO_GL")
        raise ConfigError(f"MuJoCo cannot load with MUJOCO_GL={gl!r} ({one_line(exc)}); valid: egl (Debian "
                          "libegl1 libegl-mesa0 libgl1-mesa-dri), osmesa (libosmesa6), glfw (a display), or unset"
                          if gl else f"MuJoCo cannot load: {one_line(exc)}") from None
