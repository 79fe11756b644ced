"""Arms found in a model: the chains of hinge (and slide) joints from the root to the hands, named left and right.

The joints make a tree (a joint's parent is the next joint towards the root). A branch shorter than
:data:`MIN_ARM_JOINTS` hanging beside another branch (fingers at a wrist, a head on a chest) is not an arm: its joints
become a joint group of their own. Each remaining leaf gives an arm, root to leaf; joints that several arms share
(a waist, a chest) become the group ``torso``; with more than two, those ending at the robot's feet are legs
(:data:`LEG_SHARE`), the joint group ``legs``. Two arms are told apart by their names (``left``/``right``,
``l``/``r``, ``L``/``R`` in the same place of otherwise equal names), else by mirror symmetry: the arm whose hand
is further along +y at home is ``left``, and comes first.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco

from nextage_qp.robots.modelfile import descendants, moved_by

MIN_ARM_JOINTS = 4
"""Joints an arm has at least, root to hand (shared joints included)."""
LEG_SHARE = 0.2
"""With more than two chains, one whose end at home is in the lowest this share of the robot's height is a leg (a
humanoid's, a quadruped's): it stands, it does not handle. Legs become joint groups (``legs``), not arms."""
SIDES = (("left", "right"), ("Left", "Right"), ("LEFT", "RIGHT"), ("l", "r"), ("L", "R"))
"""Name parts that tell a left arm's joints from a right arm's."""
_MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


@dataclass(frozen=True)
class FoundArm:
    """An arm found in a model: its own joints (shared ones left out), its bodies and its end-effector frame."""

    name: str
    joints: tuple[int, ...]
    bodies: tuple[int, ...]
    wrist: str


@dataclass(frozen=True)
class FoundArms:
    """The arms of a model (the +y one first when there are two), the shared joints and the other joint groups."""

    arms: tuple[FoundArm, ...]
    torso: tuple[int, ...]
    groups: dict[str, tuple[int, ...]]


def _joint_tree(model: mujoco.MjModel) -> dict[int, list[int]]:
    """Children of each moving joint in the joint tree; -1 holds the roots."""
    children: dict[int, list[int]] = {-1: []}
    for j in range(model.njnt):
        if int(model.jnt_type[j]) not in _MOVING:
            continue
        chain = [k for k in moved_by(model, int(model.jnt_bodyid[j])) if int(model.jnt_type[k]) in _MOVING]
        parent = chain[chain.index(j) - 1] if chain.index(j) else -1
        children.setdefault(parent, []).append(j)
        children.setdefault(j, [])
    return children


def _height(children: dict[int, list[int]], j: int) -> int:
    return 1 + max((_height(children, c) for c in children[j]), default=0)


def _subtree(children: dict[int, list[int]], j: int) -> list[int]:
    return [j, *(k for c in children[j] for k in _subtree(children, c))]


def chains(model: mujoco.MjModel) -> tuple[list[list[int]], list[list[int]]]:
    """Root-to-leaf joint chains of the arm tree, and the minor branches left out of it (see the module doc)."""
    children = _joint_tree(model)
    paths: list[list[int]] = []
    minor: list[list[int]] = []

    def walk(j: int, path: list[int]) -> None:
        kids = children[j]
        major = [c for c in kids if (len(kids) == 1 and j != -1) or _height(children, c) >= MIN_ARM_JOINTS]
        minor.extend(_subtree(children, c) for c in kids if c not in major)
        if not major and j != -1:
            paths.append(path)
        for c in major:
            walk(c, [*path, c])

    walk(-1, [])
    arms = [p for p in paths if len(p) >= MIN_ARM_JOINTS]
    minor += [p for p in paths if len(p) < MIN_ARM_JOINTS]
    return arms, minor


def end_effector(model: mujoco.MjModel, joints: tuple[int, ...]) -> str:
    """The arm's hand frame: the last site fixed to its last moving body, else the last body fixed to it."""
    last = int(model.jnt_bodyid[joints[-1]])
    fixed = [b for b in descendants(model, last) if int(model.body_weldid[b]) == int(model.body_weldid[last])]
    sites = [s for s in range(model.nsite) if int(model.site_bodyid[s]) in fixed and model.site(s).name]
    if sites:
        return str(model.site(sites[-1]).name)
    named = [b for b in fixed if model.body(b).name]
    return str(model.body(named[-1] if named else last).name)


def _swaps(a: str, b: str) -> bool:
    """True when ``a`` becomes ``b`` by turning one left-side name part into the right-side one."""
    for left, right in SIDES:
        for match in re.finditer(re.escape(left), a):
            if a[: match.start()] + right + a[match.end():] == b:
                return True
    return False


def left_by_name(a: list[str], b: list[str]) -> int | None:
    """0 when the names of joints ``a`` say left against ``b``, 1 when ``b``'s do, None when they do not tell."""
    votes = sum(_swaps(x, y) - _swaps(y, x) for x, y in zip(a, b, strict=False))
    return None if votes == 0 else (0 if votes > 0 else 1)


def _group_name(model: mujoco.MjModel, joints: list[int], taken: set[str], base: str | None = None) -> str:
    """A group name from the joints' common name prefix (``NECK_JOINT0``, ``NECK_JOINT1`` -> ``neck``)."""
    names = [model.joint(j).name for j in joints]
    prefix = names[0]
    for n in names[1:]:
        while not n.startswith(prefix):
            prefix = prefix[:-1]
    words = [w for w in re.split(r"[^a-z0-9]+", prefix.lower()) if w and w not in ("joint", "jnt")]
    base = base or "_".join(words).rstrip("_0123456789") or re.sub(r"[^a-z0-9]+", "_", model.body(
        int(model.jnt_bodyid[joints[0]])).name.lower()).strip("_") or "group"
    name, k = base, 1
    while name in taken:
        k += 1
        name = f"{base}{k}"
    taken.add(name)
    return name


def find_arms(model: mujoco.MjModel, data: mujoco.MjData, single: str = "arm") -> FoundArms:
    """The arms of a model, named and ordered (``data`` holds the home pose, kinematics done).

    Two arms are ``left`` and ``right``, one arm is ``single`` (e.g. the robot's name), more are ``arm1``... by y.
    """
    paths, minor = chains(model)
    shared = sorted({j for p in paths for j in p if sum(j in q for q in paths) > 1})
    own = [[j for j in p if j not in shared] for p in paths]
    own = [o for o in own if o]
    grip: list[list[int]] = []
    for k, o in enumerate(own):  # trailing slide joints after hinges: a gripper, not the arm
        cut = len(o)
        while cut > 1 and int(model.jnt_type[o[cut - 1]]) == int(mujoco.mjtJoint.mjJNT_SLIDE):
            cut -= 1
        if any(int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) for j in o[:cut]):
            own[k], tail = o[:cut], o[cut:]
            grip.append(tail)
        else:
            grip.append([])
    legs: list[list[int]] = []
    if len(own) > 2:  # a humanoid's or a quadruped's legs end where it stands
        z = data.xpos[1:, 2]
        low = float(z.min()) + LEG_SHARE * float(z.max() - z.min())
        high = [float(data.xpos[int(model.jnt_bodyid[o[-1]])][2]) >= low for o in own]
        if any(high):  # (every chain low: no arm to tell legs from, all stay arms)
            legs = [o for o, h in zip(own, high, strict=True) if not h]
            own = [o for o, h in zip(own, high, strict=True) if h]
            grip = [g for g, h in zip(grip, high, strict=True) if h]
    hand_y = [float(data.xpos[int(model.jnt_bodyid[o[-1]])][1]) for o in own]
    order = sorted(range(len(own)), key=lambda k: -hand_y[k])
    names = [single] if len(own) == 1 else [f"arm{i + 1}" for i in range(len(own))]
    if len(own) == 2:
        by_name = left_by_name(*([model.joint(j).name for j in o] for o in own))
        if by_name is not None:
            order = [by_name, 1 - by_name]
        names = ["left", "right"]
    arms = []
    for name, k in zip(names, order, strict=True):
        joints = tuple(own[k])
        bodies = tuple(dict.fromkeys(int(model.jnt_bodyid[j]) for j in joints))
        arms.append(FoundArm(name, joints, bodies, end_effector(model, joints)))
    taken = {"torso", *(f"{a.name}_arm" for a in arms)}
    groups: dict[str, tuple[int, ...]] = {}
    for name, k in zip(names, order, strict=True):
        if grip[k]:
            taken.add(f"{name}_gripper")
            groups[f"{name}_gripper"] = tuple(grip[k])
    if legs:
        leg_joints = sorted(j for leg in legs for j in leg)
        groups[_group_name(model, leg_joints, taken, "legs")] = tuple(leg_joints)
    for branch in minor:
        parent = [j for j in moved_by(model, int(model.jnt_bodyid[branch[0]])) if j < branch[0]][-1:]
        arm = next((a for a in arms if parent and parent[0] in a.joints), None)
        base = f"{arm.name}_gripper" if arm else None
        name = base if base and base not in taken else _group_name(model, branch, taken, base)
        taken.add(name)
        groups[name] = tuple(sorted(branch))
    return FoundArms(tuple(arms), tuple(shared), groups)
