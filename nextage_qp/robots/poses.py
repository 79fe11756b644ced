"""Poses of a model on its own: a home free of self-contact, static joint torques, the lowest collision point."""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from nextage_qp.robots.modelfile import self_contacts

HOME_SAMPLES = 400
"""Random poses ``robot init`` tries, after ``qpos0`` and the range midpoints, to find a home without contacts."""
HOME_SEED = 0
"""Seed of those samples: the same model always gets the same home."""
HOME_MARGIN = 0.1
"""Share of each limited joint's range a drafted home keeps off its limits: a joint at a limit can move one way only,
and a limit is often where an arm is stretched straight (the PR2's elbows at qpos0), a singular pose that a
differential IK cannot leave towards targets nearer the shoulder."""
TORQUE_FACTOR = 3.0
"""A joint's default torque limit is this many times its largest static (gravity) torque over a few poses..."""
TORQUE_FLOOR_NM = 5.0
"""...and at least this [N m]."""


class Home(NamedTuple):
    """A home pose: the full ``qpos``, how it was found, and the body pairs still in contact there."""

    qpos: np.ndarray
    how: str
    contacts: list[tuple[str, str]]


def _limits(model: mujoco.MjModel, joints: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``qpos`` addresses, lower and upper bounds of the joints (unlimited hinges: +-pi; slides: +-0.1 m)."""
    adr = model.jnt_qposadr[joints]
    limited = model.jnt_limited[joints].astype(bool)
    hinge = model.jnt_type[joints] == mujoco.mjtJoint.mjJNT_HINGE
    wide = np.where(hinge, np.pi, 0.1)
    return adr, np.where(limited, model.jnt_range[joints, 0], -wide), np.where(limited, model.jnt_range[joints, 1],
                                                                              wide)


def find_home(model: mujoco.MjModel, joints: list[int]) -> Home:
    """A pose of ``joints`` without contact between the model's bodies (world excluded), found deterministically.

    Tried in order: ``qpos0`` clipped to the ranges, the range midpoints, then :data:`HOME_SAMPLES` seeded random
    poses around those two, the spread growing from 5 % to 50 % of each range; every one kept :data:`HOME_MARGIN` of
    each limited joint's range off its limits. The first pose without contacts wins; if none is free, the one with the
    fewest contact pairs (they are reported).
    """
    data = mujoco.MjData(model)
    adr, lo, hi = _limits(model, joints)
    inset = np.where(model.jnt_limited[joints].astype(bool), HOME_MARGIN * (hi - lo), 0.0)
    lo, hi = lo + inset, hi - inset
    zero = np.clip(model.qpos0[adr], lo, hi)
    mid = (lo + hi) / 2
    rng = np.random.default_rng(HOME_SEED)
    best: Home | None = None
    for k in range(HOME_SAMPLES + 2):
        if k < 2:
            q, how = (zero, "qpos0 clipped to the ranges, off their limits") if k == 0 else (mid, "the range midpoints")
        else:
            spread = 0.05 + 0.45 * (k - 2) / HOME_SAMPLES
            centre = zero if k % 2 == 0 else mid
            q = np.clip(centre + rng.normal(0.0, spread, len(joints)) * (hi - lo), lo, hi)
            how = f"seeded sample {k - 1} near {'qpos0' if k % 2 == 0 else 'the range midpoints'}"
        qpos = model.qpos0.copy()
        qpos[adr] = q
        contacts = self_contacts(model, data, qpos)
        if best is None or len(contacts) < len(best.contacts):
            best = Home(qpos, how, contacts)
        if not contacts:
            break
    assert best is not None
    return best


def static_torques(model: mujoco.MjModel, joints: list[int], home: np.ndarray, poses: int = 8) -> np.ndarray:
    """Each joint's largest |gravity torque| [N m] over ``home`` and ``poses`` seeded random poses in range."""
    data = mujoco.MjData(model)
    adr, lo, hi = _limits(model, joints)
    dofs = model.jnt_dofadr[joints]
    rng = np.random.default_rng(HOME_SEED)
    peak = np.zeros(len(joints))
    for k in range(poses + 1):
        data.qpos[:] = home
        if k:
            data.qpos[adr] = rng.uniform(lo, hi)
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        peak = np.maximum(peak, np.abs(data.qfrc_bias[dofs]))
    return peak


def default_torque_limit(static_nm: float) -> float:
    """:data:`TORQUE_FACTOR` x the static torque, at least :data:`TORQUE_FLOOR_NM`, rounded up to 1 N m."""
    return float(np.ceil(max(TORQUE_FACTOR * static_nm, TORQUE_FLOOR_NM)))


def lowest_point(model: mujoco.MjModel, qpos: np.ndarray) -> float | None:
    """World z [m] of the lowest point of the bodies' collision geoms at ``qpos`` (bounding boxes), or None."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    low = None
    for g in range(model.ngeom):
        if not model.geom_bodyid[g] or not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        rot = data.geom_xmat[g].reshape(3, 3)
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        z = float(data.geom_xpos[g][2] + rot[2] @ centre - np.abs(rot[2]) @ half)
        low = z if low is None else min(low, z)
    return low
