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
from nextage_qp.manipulation.phases.grasp.phase import Grasp, GraspSpec
from nextage_qp.manipulation.phases.joints import Joints, JointsSpec
from nextage_qp.manipulation.phases.move import Move, MoveSpec
from nextage_qp.manipulation.phases.place import Place, PlaceSpec
from nextage_qp.manipulation.phases.push.phase import Push, PushSpec
from nextage_qp.manipulation.phases.release import Release, ReleaseSpec
from nextage_qp.manipulation.phases.wait import Wait, WaitSpec

_REGISTRY: dict[str, tuple[type[Spec], type[Phase]]] = {}
BUILT_IN: frozenset[str] = frozenset()
REGISTRY = MappingProxyType(_REGISTRY)
"""Phase kind -> (its spec model, its behaviour class), in registration order."""


def register(spec: type[Spec], phase: type[Phase]) -> None:
    """Add a phase kind (the value of ``spec``'s ``kind`` literal); a kind registered again is replaced.

    Raises:
        TypeError: ``spec`` is no Spec subclass with a one-value ``kind: Literal[...]``, or ``phase`` no Phase
            subclass, or the kind is a built-in one registered with other classes.
    """
    if not (isinstance(spec, type) and issubclass(spec, Spec)) or not (isinstance(phase, type)
                                                                       and issubclass(phase, Phase)):
        raise TypeError(f"register({spec!r}, {phase!r}): give a Spec subclass and a Phase subclass")
    kind = spec.kind_name()
    if kind in BUILT_IN and _REGISTRY.get(kind) not in (None, (spec, phase)):
        raise TypeError(f"register: {kind!r} is a built-in phase kind; give yours another kind name")
    _REGISTRY[kind] = (spec, phase)


def unregister(kind: str) -> None:
    """Remove a phase kind added with :func:`register`.

    Raises:
        KeyError: ``kind`` is built in, or not registered (the message lists the kinds that may be removed).
    """
    if kind in BUILT_IN or kind not in _REGISTRY:
        added = sorted(set(_REGISTRY) - BUILT_IN)
        raise KeyError(f"unregister: {kind!r} is {'a built-in phase kind' if kind in BUILT_IN else 'not registered'}; "
                       f"kinds added that may be removed: {', '.join(added) or 'none'}")
    del _REGISTRY[kind]


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
BUILT_IN = frozenset(_REGISTRY)
"""The kinds this package registers, which :func:`register` does not replace and :func:`unregister` keeps."""

__all__ = ["REGISTRY", "Phase", "Spec", "build", "names_in", "register", "unregister"]
