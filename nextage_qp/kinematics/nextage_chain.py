"""The Nextage's joint table as a transform chain: the report's own forward kinematics, the model's cross-check.

Written from the spec's joint table (URDF joint origins and axes), independently of the MJCF: tests compare MuJoCo's
forward kinematics of ``robots/nextage/nextage.xml`` against :func:`~nextage_qp.kinematics.frames.chain_fk` over this
topology. Only the Nextage's own files name its joints; generic code takes every name from a robot file.
"""

from __future__ import annotations

from types import MappingProxyType

CHEST_JOINT = "CHEST_JOINT0"
HEAD_JOINTS = ("HEAD_JOINT0", "HEAD_JOINT1")
ARM_PREFIXES = (("LARM", 1.0), ("RARM", -1.0))
"""Each arm's URDF prefix and its side's sign (the arms mirror each other in y)."""

BASE_HEIGHT = 0.85
"""Height of the base (and WAIST) frame above the floor [m]."""

_ARM_CHAIN: dict[int, tuple[str | int, tuple[float, ...], tuple[float, ...]]] = {
    0: (CHEST_JOINT, (0.04, 0.135, 0.1015), (0, 0, 1)),
    1: (0, (0.0, 0.0, 0.066), (0, 1, 0)),
    2: (1, (0.0, 0.095, -0.25), (0, 1, 0)),
    3: (2, (0.1805, 0.0, -0.03), (1, 0, 0)),
    4: (3, (0.1495, 0.0, 0.0), (0, 1, 0)),
    5: (4, (0.0, 0.0, -0.1335), (0, 0, 1)),
}


def _topology() -> dict[str, tuple[str | None, tuple[float, ...], tuple[float, ...]]]:
    topo: dict[str, tuple[str | None, tuple[float, ...], tuple[float, ...]]] = {
        CHEST_JOINT: (None, (0.0, 0.0, BASE_HEIGHT + 0.267), (0, 0, 1)),
        HEAD_JOINTS[0]: (CHEST_JOINT, (0.0, 0.0, 0.302), (0, 0, 1)),
        HEAD_JOINTS[1]: (HEAD_JOINTS[0], (0.0, 0.0, 0.08), (0, 1, 0)),
    }
    for prefix, sign in ARM_PREFIXES:
        joints = [f"{prefix}_JOINT{i}" for i in range(6)]
        for i, (parent, origin, axis) in _ARM_CHAIN.items():
            parent_name = parent if isinstance(parent, str) else joints[parent]
            topo[joints[i]] = (parent_name, (origin[0], sign * origin[1], origin[2]), axis)
    return topo


TOPOLOGY = MappingProxyType(_topology())
"""joint -> (parent joint, origin [m] in the parent link frame, axis); the base is the world at (0, 0, BASE_HEIGHT)."""
