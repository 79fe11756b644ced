"""A random-dot texture on the world's surfaces, for stereo block matching (:mod:`nextage_qp.sensing.camera.stereo`)."""

from __future__ import annotations

from collections.abc import Collection

import mujoco

TEXTURE, MATERIAL = "stereo_speckle", "stereo_speckle"
"""Names of the texture and material added."""
DOTS = 0.4
"""Share of the texture's pixels that are light dots."""
REPEAT = 3.0
"""Texture repeats per metre (256 pixels each: dots of about 1.3 mm)."""


def speckle(spec: mujoco.MjSpec, robot_bodies: Collection[str]) -> None:
    """Give every geom of ``spec`` not on one of ``robot_bodies`` a random-dot texture (its colour kept as a tint).

    The geoms' physics is unchanged; only how the cameras see them.
    """
    spec.add_texture(name=TEXTURE, type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_FLAT,
                     mark=mujoco.mjtMark.mjMARK_RANDOM, random=DOTS, width=256, height=256,
                     rgb1=[0.3, 0.3, 0.3], markrgb=[1.0, 1.0, 1.0])
    material = spec.add_material(name=MATERIAL)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = TEXTURE
    material.texuniform, material.texrepeat = True, [REPEAT, REPEAT]
    skip = set(robot_bodies)
    for geom in spec.geoms:
        if geom.parent.name not in skip and geom.type != mujoco.mjtGeom.mjGEOM_PLANE:
            geom.material = MATERIAL
