"""The Nextage's vocabulary.

Joint names, the two arms with their links and sites, the torso and head, and the report's transform-chain topology.
Every other module takes these names from here or from a :class:`Robot`.

The names are the URDF's (``CHEST_JOINT0``, ``LARM_JOINT0`` ... , bodies ``LARM_JOINT5_Link`` ...), so every
table of the report maps 1:1; the sites are the MJCF's (``left_tool``, ``left_pad`` ...).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

CHEST_JOINT = "CHEST_JOINT0"
HEAD_JOINTS = ("HEAD_JOINT0", "HEAD_JOINT1")


@dataclass(frozen=True)
class Arm:
    """One arm: its joints, links and named sites.

    Attributes:
        side: ``left`` or ``right``.
        prefix: URDF prefix, ``LARM`` or ``RARM``.
        sign: +1 for the left arm, -1 for the right (the arms mirror each other in y).
    """

    side: str
    prefix: str
    sign: float

    @property
    def joints(self) -> tuple[str, ...]:
        """``PREFIX_JOINT0`` ... ``PREFIX_JOINT5``, shoulder to wrist."""
        return tuple(f"{self.prefix}_JOINT{i}" for i in range(6))

    @property
    def links(self) -> tuple[str, ...]:
        """The six link bodies, shoulder to wrist."""
        return tuple(f"{j}_Link" for j in self.joints)

    @property
    def forearm_links(self) -> tuple[str, ...]:
        """Links 3-5 (upper arm roll, wrist pitch, wrist)."""
        return self.links[3:]

    @property
    def hand_link(self) -> str:
        """The wrist link, whose cylinder and camera box are the hand."""
        return self.links[5]

    @property
    def wrist_site(self) -> str:
        """Site at the wrist frame (``LARM_JOINT5``'s origin)."""
        return f"{self.side}_wrist"

    @property
    def tool_site(self) -> str:
        """Site at the front face of the camera box, for pushing."""
        return f"{self.side}_tool"

    @property
    def pad_site(self) -> str:
        """Site on the inner face of the wrist cylinder, for clamping."""
        return f"{self.side}_pad"


ARMS = (Arm("left", "LARM", 1.0), Arm("right", "RARM", -1.0))
"""Both arms, left first: the order every per-arm loop uses."""

JOINT_NAMES: tuple[str, ...] = (CHEST_JOINT, *HEAD_JOINTS, *ARMS[0].joints, *ARMS[1].joints)
"""The 15 robot joints, in model (and URDF) order."""

GROUP_JOINTS = MappingProxyType(
    {"chest": (CHEST_JOINT,), "head": HEAD_JOINTS, **{f"{arm.side}_arm": arm.joints for arm in ARMS}}
)
"""Joint groups: the chest, the head and each arm."""

TORSO_BODIES = ("CHEST_JOINT0_Link", "WAIST", "nextage_base")
HEAD_BODIES = ("HEAD_JOINT0_Link", "HEAD_JOINT1_Link")
BASE_BODY = "base_link"

TOOL_SITES = tuple(site for arm in ARMS for site in (arm.tool_site, arm.pad_site))
"""Sites a manipulation run records and marks: each arm's tool and pad."""

ROBOT_COLLISION_GROUPS = MappingProxyType(
    {
        **{f"{arm.side}_arm": arm.links for arm in ARMS},
        **{f"{arm.side}_forearm": arm.forearm_links for arm in ARMS},
        **{f"{arm.side}_hand": (arm.hand_link,) for arm in ARMS},
        "torso": TORSO_BODIES,
        "head": HEAD_BODIES,
    }
)
"""Collision groups of the robot by body; a scene adds ``table``, ``obstacle`` and one group per object."""

SCENE_GROUP_BODIES = ("table", "obstacle")
"""Static scene bodies that become collision groups of their own when a scene has them."""

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
    for arm in ARMS:
        for i, (parent, origin, axis) in _ARM_CHAIN.items():
            parent_name = parent if isinstance(parent, str) else arm.joints[parent]
            topo[arm.joints[i]] = (parent_name, (origin[0], arm.sign * origin[1], origin[2]), axis)
    return topo


TOPOLOGY = MappingProxyType(_topology())
"""joint -> (parent joint, origin [m] in the parent link frame, axis), written from the spec's joint table (the
report's method, independent of the MJCF); the base is the world at (0, 0, BASE_HEIGHT)."""
