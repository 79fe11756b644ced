"""The contract of a phase kind: a spec (its YAML schema) and a behaviour (start, then one command per tick).

A spec is a pydantic model with a ``kind`` literal. Fields that hold names of the scene are declared with
:func:`name_field`, so the runner checks every name of every kind in one loop (:func:`names_in`). A behaviour
subclasses :class:`Phase` and fills two methods, as mink's tasks fill two.
"""

from __future__ import annotations

import typing
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, Field, model_validator

from nextage_qp.errors import InfeasibleError, NextageQPError, PhaseError
from nextage_qp.geometry import Pose
from nextage_qp.io.schema import YamlModel
from nextage_qp.io.yaml_file import MAX_SECONDS, NameKind, name_field
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.clamp import Clamp
from nextage_qp.manipulation.context import Grip, View, refusal

__all__ = ["MAX_SECONDS", "NameKind", "Phase", "Spec", "name_field"]

DEFAULT_TIMEOUT = 10.0
"""A phase's timeout [s] when none is given and its kind estimates no budget; the least timeout derived from one."""
TIMEOUT_MARGIN = 2.0
"""A phase without a ``timeout`` times out after this many times its budget (:meth:`Phase.budget`)."""
SETTLE_S = 1.0
"""Time [s] a budget allows for the robot to come to rest after a motion."""


def plan_field() -> Any:
    """The ``plan`` key of a phase whose motion is checked against the world (push, grasp, place, release)."""
    return Field(default="auto", description="The transit's joint-space legs: planned around obstacles where the "
                                             "straight leg would touch one (auto), always planned, or driven straight "
                                             "(never).")


class Spec(YamlModel):
    """Fields every phase has; subclasses add ``kind: Literal[...]`` and their own."""

    grip: ClassVar[str | None] = None
    """How the phase uses the clamp: ``"makes"`` one (grasp), ``"needs"`` one on its object from an earlier phase
    (carry, place), ``"ends"`` it (needs it, then lets go: release), or None."""

    kind: str
    name: str | None = Field(default=None, description="Label in progress and results (default: kind + index).")
    timeout: float | None = Field(
        default=None, gt=0, le=MAX_SECONDS,
        description=f"Simulated time before the phase fails [s]. Unset: {TIMEOUT_MARGIN:g} times the phase's budget, "
                    "the time its distances take at its speeds with every approach or correction it may make, worked "
                    f"out when it starts (at least {DEFAULT_TIMEOUT:g} s; {DEFAULT_TIMEOUT:g} s for a kind that has "
                    "no budget).")

    @model_validator(mode="after")
    def _object_is_not_its_own_goal(self) -> Spec:
        obj = getattr(self, "object", None)
        for key in ("target", "place_at"):
            if obj is not None and getattr(self, key, None) == obj:
                raise ValueError(f"{key}: {obj!r} is the phase's object itself; name the body it should go to")
        return self

    @classmethod
    def kind_name(cls) -> str:
        """The value of the spec's ``kind`` literal.

        Raises:
            TypeError: ``kind`` is no ``Literal`` of one string.
        """
        field = cls.model_fields.get("kind")
        args = typing.get_args(field.annotation) if field is not None else ()
        if field is None or typing.get_origin(field.annotation) is not typing.Literal or len(args) != 1 \
                or not isinstance(args[0], str):
            raise TypeError(f"register: {cls.__name__}.kind must be a Literal of one string, e.g. kind: "
                            "Literal['my_phase']")
        return args[0]


def names_in(model: BaseModel, key: str) -> Iterator[tuple[str, NameKind, str]]:
    """Every (dotted key, kind, name) a spec refers to, through nested models and lists of them."""
    for field, info in type(model).model_fields.items():
        value = getattr(model, field)
        where = f"{key}.{field}"
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        kind = extra.get("names")
        if kind is not None:
            if isinstance(value, str):
                yield where, kind, value  # type: ignore[misc]
            elif isinstance(value, dict):
                yield from ((where, kind, k) for k in value)  # type: ignore[misc]
            elif value is not None:
                yield from ((f"{where}[{i}]", kind, v) for i, v in enumerate(value))  # type: ignore[misc]
        elif isinstance(value, BaseModel):
            yield from names_in(value, where)
        elif isinstance(value, (list, tuple)):
            for i, item in enumerate(value):
                if isinstance(item, BaseModel):
                    yield from names_in(item, f"{where}[{i}]")


class Phase(ABC):
    """A phase of a run: :meth:`start` once, then :meth:`update` every control tick until a command is done.

    Args:
        spec: The phase's validated spec.
        name: Its label.

    Attributes:
        info: Figures the phase reports in the run's result (attempts, errors, ...).
    """

    spec_type: ClassVar[type[Spec]]

    def __init__(self, spec: Any, name: str) -> None:
        self.spec, self.name = spec, name
        self.t0 = 0.0
        self.timeout = DEFAULT_TIMEOUT if spec.timeout is None else float(spec.timeout)  # the runner's, at the start
        self.info: dict[str, Any] = {}

    @abstractmethod
    def start(self, view: View) -> None:
        """Called on the tick the phase begins (``view`` shows the state at that tick)."""

    @abstractmethod
    def update(self, view: View) -> Command:
        """This tick's command; ``done=True`` ends the phase after the tick."""

    def budget(self, view: View) -> float | None:
        """The simulated time [s] the phase takes with every approach or correction it may make, from the distances it
        has to cover and the speeds its spec gives; asked once, right after :meth:`start`. None (the default): none.

        A phase without a ``timeout`` fails after :data:`TIMEOUT_MARGIN` times this (:meth:`time_limit`), so a task
        written once gets the time its scene needs on any robot: a farther target, a slower speed, more tries.
        """  # noqa: D205
        return None

    def time_limit(self, view: View) -> tuple[float, float | None]:
        """The phase's timeout [s] and the budget it was derived from (None: the spec's ``timeout``, or no budget).

        Asked once, right after :meth:`start`.
        """
        if self.spec.timeout is not None:
            return float(self.spec.timeout), None
        budget = self.budget(view)
        if budget is None or not np.isfinite(budget):
            return DEFAULT_TIMEOUT, None
        return min(MAX_SECONDS, max(DEFAULT_TIMEOUT, TIMEOUT_MARGIN * budget)), float(budget)

    def grip(self, current: Grip | None) -> Grip | None:
        """The clamp in force after this phase's start or latest update (default: unchanged)."""
        return current

    def carrier(self, view: View) -> tuple[str, Callable[[], Pose]] | None:
        """The object this phase moves with the robot without clamping it, and the pose (asked each tick) moving it.

        E.g. a push in contact that the camera cannot see: the object's pose estimate then follows the tool's advance.
        None (the default) when there is none. Asked once per control tick, after the phase's update.
        """
        return None

    def stalled(self, view: View) -> str | None:
        """What held the phase up, in a few words, when it times out (None, the default: nothing it can name).

        The runner puts it into the timeout's message, e.g. a push whose object kept tipping under the tool.
        """
        return None

    def failure(self, message: str, error: type[PhaseError] | type[InfeasibleError] = PhaseError) -> NextageQPError:
        """The error that fails this phase: ``message`` after the phase's name and kind, the phase in its field.

        ``error``: :class:`InfeasibleError` for a refusal before anything moved (:func:`~.context.refusal`).
        """
        return error(f"phase {self.name!r} ({self.spec.kind}): {message}", phase=self.name)

    def refusal(self, view: View, message: str) -> NextageQPError:
        """The error of a phase that finds its task impossible: a refusal (exit 2) while nothing has moved yet."""
        return self.failure(message, refusal(view))

    def held(self, view: View, obj: str, relative_cost: float) -> Clamp:
        """The clamp on ``obj`` that an earlier grasp left, driven with ``relative_cost``; fails without one."""
        grip = view.grip
        if grip is None or grip.object != obj:
            raise self.failure(f"needs {obj!r} clamped by a grasp phase first")
        return Clamp(grip, relative_cost)
