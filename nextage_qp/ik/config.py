"""Configuration of the QP inverse kinematics: costs, regularisation, limits and solver (YAML-ready).

Every field has one default, a unit in its description, and a validator; unknown keys are errors. Names
(frames, joints, geom groups) are checked against the robot when :class:`~nextage_qp.ik.qp.QPIK` is built.
"""

from __future__ import annotations

from typing import Literal

import qpsolvers
from pydantic import Field, field_validator, model_validator

from nextage_qp.io.schema import YamlModel
from nextage_qp.robots.model import GroupSpec


class CollisionPairConfig(YamlModel):
    """Collision avoidance between two named geom groups (see :meth:`Robot.collision_geoms`).

    Every geom of group ``a`` is kept at least ``min_distance`` from every geom of group ``b``; the
    constraint is sent to the QP only while the pair is closer than ``detection_distance``. A group paired with
    itself (``a`` = ``b``) keeps its own links apart: an arm that would fold its forearm onto its upper arm. Its
    links that touch where they join (a parent and its child), and pairs of its geoms nearer than ``min_distance``
    at the robot's home, are left out.
    """

    a: str = Field(description="First geom group, e.g. 'left_arm'.")
    b: str = Field(description="Second geom group, e.g. 'table'; 'a' again: the group's own links kept apart.")
    min_distance: float = Field(default=0.005, ge=0.0, description="Distance kept between the groups [m].")
    detection_distance: float = Field(
        default=0.05, gt=0.0, description="Distance below which the pair becomes a QP constraint [m]."
    )

    @model_validator(mode="after")
    def _detection_beyond_minimum(self) -> CollisionPairConfig:
        if self.detection_distance <= self.min_distance:
            raise ValueError(
                f"detection_distance ({self.detection_distance} m) must exceed min_distance ({self.min_distance} m)"
            )
        return self


class CollisionGroupConfig(YamlModel):
    """A named geom group of its own.

    Every collision geom of the listed bodies and of the subtrees below the listed roots (e.g. ``{subtrees:
    [FOREARM_LINK]}`` for a forearm).
    """

    bodies: tuple[str, ...] = Field(default=(), description="Bodies whose collision geoms are in the group.")
    subtrees: tuple[str, ...] = Field(
        default=(), description="Bodies whose collision geoms, and those of every body below them, are in the group."
    )

    @model_validator(mode="after")
    def _something(self) -> CollisionGroupConfig:
        if not self.bodies and not self.subtrees:
            raise ValueError("a collision group needs bodies or subtrees")
        return self


class IKConfig(YamlModel):
    r"""Differential IK as a QP: task costs, regularisation, limits and solver.

    The QP solved each step (mink's formulation, :math:`\Delta q = v\,dt`) is

    .. math::

        \min_{\Delta q}\ \sum_i \|W_i (J_i \Delta q + e_i)\|^2
            + w_p^2 \|\Delta q + q - q_p\|^2 + (\lambda + \mu \|W e\|^2) \|\Delta q\|^2
        \quad \text{s.t.}\quad \text{joint box},\ \text{collision rows}

    with frame errors :math:`e_i` (position [m], rotation [rad]), weights :math:`W_i` from the position and
    orientation costs, posture weight :math:`w_p`, constant damping :math:`\lambda` and
    Levenberg–Marquardt damping :math:`\mu`.
    """

    position_cost: float = Field(default=1.0, ge=0.0, description="Weight of frame position errors [1/m].")
    orientation_cost: float = Field(default=1.0, ge=0.0, description="Weight of frame orientation errors [1/rad].")
    posture_cost: float = Field(default=1e-4, ge=0.0, description="Weight of the posture task [1/rad].")
    posture_target: Literal["home", "zero"] | dict[str, float] = Field(
        default="home", description="Posture the redundancy is pulled towards: a keyframe or joint -> [rad]."
    )
    damping: float = Field(default=1e-6, ge=0.0, description="Constant Tikhonov damping on dq [unitless].")
    lm_damping: float = Field(
        default=0.01, ge=0.0, description="Levenberg–Marquardt damping, scaled by the squared task error [unitless]."
    )
    solver: str = Field(default="daqp", description="qpsolvers backend (daqp, osqp, proxqp, ...).")
    dt: float = Field(default=0.2, gt=0.0, description="Integration step of solve() [s].")
    max_iters: int = Field(default=200, ge=1, description="Iteration cap of solve() [count].")
    pos_tol: float = Field(default=1e-4, gt=0.0, description="Position tolerance of solve() [m].")
    rot_tol: float = Field(default=1e-3, gt=0.0, description="Orientation tolerance of solve() [rad].")
    velocity_limit: float | dict[str, float] = Field(
        default=3.0, description="Joint speed limit [rad/s]: one value or joint -> value (others at 3.0)."
    )
    limit_margin: float = Field(
        default=0.0, ge=0.0, le=0.5, description="Distance the IK keeps from every joint limit [rad]."
    )
    limit_gain: float = Field(
        default=0.95, gt=0.0, le=1.0, description="Fraction [1] of the distance to a joint limit allowed per step."
    )
    restarts: int = Field(
        default=100, ge=0,
        description="solve(): random in-limit restarts after a descent stalls (local minimum) [count]."
    )
    seed: int = Field(default=0, description="Seed of the restart configurations [-] (solve() is deterministic).")
    collision_pairs: tuple[CollisionPairConfig, ...] = Field(
        default=(), description="Geom-group pairs kept apart (e.g. left_arm/table)."
    )
    collision_groups: dict[str, CollisionGroupConfig] = Field(
        default_factory=dict, description="Extra geom groups for collision_pairs, by body or subtree."
    )
    collision_gain: float = Field(
        default=0.85, gt=0.0, le=1.0, description="Fraction [1] of the gap to min_distance a pair may close per step."
    )
    base_cost: float = Field(
        default=2.0, ge=0.0, allow_inf_nan=False,
        description="A mobile robot's base: cost of its planar step [per m and rad]; more than the arms' joints "
                    "cost, so the arms reach near and the base drives far.",
    )
    stall_iters: int = Field(
        default=8, ge=1,
        description="solve(): a descent stalls after this many iterations without 1 % progress [count]."
    )
    trust_region: bool = Field(
        default=False, description=(
            "Servo: halve a fast IK step that turns back on the last one under an unchanged command (damps the "
            "IK's limit cycle at slow control rates; see nextage_qp/loop/servo.py)."),
    )

    @field_validator("solver")
    @classmethod
    def _solver_installed(cls, value: str) -> str:
        if value not in qpsolvers.available_solvers:
            raise ValueError(f"solver {value!r} is not installed; available: {', '.join(qpsolvers.available_solvers)}")
        return value

    @field_validator("velocity_limit")
    @classmethod
    def _positive_velocity(cls, value: float | dict[str, float]) -> float | dict[str, float]:
        values = value.values() if isinstance(value, dict) else [value]
        if not all(v > 0 for v in values):
            raise ValueError(f"velocity_limit must be > 0 rad/s, got {value}")
        return value

    def group_specs(self) -> dict[str, GroupSpec]:
        """The extra collision groups as :class:`~nextage_qp.robots.model.GroupSpec` values."""
        return {name: GroupSpec(g.bodies, g.subtrees) for name, g in self.collision_groups.items()}

    @model_validator(mode="after")
    def _some_cost(self) -> IKConfig:
        if self.position_cost == 0.0 and self.orientation_cost == 0.0:
            raise ValueError("position_cost and orientation_cost are both 0: no frame target would have an effect")
        return self
