"""Phase kinds as plug-ins.

A registry ``kind -> (Spec, Phase)`` from which the config schema, the list of valid kinds and the name checks derive. A
new kind is one module (its spec and behaviour) and one :func:`register` line.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

from nextage_qp.manipulation.phases.base import Phase, Spec, names_in
from nextage_qp.manipulation.phases.carry import Carry, CarrySpec
from nextage_qp.manipulation.phases.drive import Drive, DriveSpec
from nextage_qp.manipulation.phases.grasp import Grasp, GraspSpec
from nextage_qp.manipulation.phases.joints import Joints, JointsSpec
from nextage_qp.manipulation.phases.move import Move, MoveSpec
from nextage_qp.manipulation.phases.place import Place, PlaceSpec
from nextage_qp.manipulation.phases.push import Push, PushSpec
from nextage_qp.manipulation.phases.release import Release, ReleaseSpec
from nextage_qp.manipulation.phases.wait import Wait, WaitSpec

_REGISTRY: dict[str, tuple[type[Spec], type[Phase]]] = {}
REGISTRY = MappingProxyType(_REGISTRY)
"""Phase kind -> (its spec model, its behaviour class), in registration order."""


def register(spec: type[Spec], phase: type[Phase]) -> None:
    """Add a phase kind (the value of ``spec``'s ``kind`` literal); a kind registered again is replaced."""
    _REGISTRY[spec.kind_name()] = (spec, phase)


def unregister(kind: str) -> None:
    """Remove a phase kind (e.g. one a test added)."""
    _REGISTRY.pop(kind, None)


def build(spec: Any, name: str) -> Phase:
    """The behaviour object of a validated spec."""
    return _REGISTRY[spec.kind][1](spec, name)


register(MoveSpec, Move)
register(PushSpec, Push)
register(GraspSpec, Grasp)
register(CarrySpec, Carry)
register(PlaceSpec, Place)
register(ReleaseSpec, Release)
register(JointsSpec, Joints)
register(WaitSpec, Wait)
register(DriveSpec, Drive)

__all__ = ["REGISTRY", "Phase", "Spec", "build", "names_in", "register", "unregister"]
