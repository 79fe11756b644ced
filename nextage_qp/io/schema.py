"""The base of every schema read from YAML: strict keys and values, and no boolean taken for a number."""

from __future__ import annotations

import collections.abc
import types
import typing
from typing import Any

from pydantic import BaseModel, model_validator

from nextage_qp.io.yaml_file import STRICT


def _number_only(annotation: Any) -> bool:
    """Whether a field takes a number and not a boolean (``int``, ``float``, or a union of them with None)."""
    args = typing.get_args(annotation) if typing.get_origin(annotation) in (typing.Union, types.UnionType) else ()
    kinds = set(args) if args else {annotation}
    return bool(kinds & {int, float}) and bool not in kinds and kinds <= {int, float, type(None)}


def _boolean_number(annotation: Any, value: Any, where: str) -> str | None:
    """Where in ``value`` a boolean stands for a number of ``annotation`` (a field, or a list or mapping of them)."""
    if typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if isinstance(value, bool):
        return where if _number_only(annotation) else None
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType) and bool not in args:  # e.g. a list or None: each kind
        return next((w for w in (_boolean_number(a, value, where) for a in args) if w is not None), None)
    if isinstance(value, dict) and origin in (dict, collections.abc.Mapping) and len(args) == 2:
        items: Any = ((f"{where}.{k}", args[1], v) for k, v in value.items())
    elif isinstance(value, (list, tuple)) and origin in (list, tuple, collections.abc.Sequence) and args:
        fixed = origin is tuple and not (len(args) == 2 and args[1] is Ellipsis)
        items = ((f"{where}[{i}]", args[i] if fixed and i < len(args) else args[0], v) for i, v in enumerate(value))
    else:
        return None
    return next((w for w in (_boolean_number(a, v, w) for w, a, v in items) if w is not None), None)


class YamlModel(BaseModel):
    """Base of every schema read from YAML: :data:`STRICT`, and a boolean is no number.

    Pydantic reads ``true`` as 1 where a number is expected; ``attempts: true`` is a typo, not one attempt.
    """

    model_config = STRICT

    @model_validator(mode="before")
    @classmethod
    def _no_boolean_numbers(cls, data: Any) -> Any:  # (a field validator on "*" hides a Literal from discriminators)
        if isinstance(data, dict):
            for name, field in cls.model_fields.items():
                key = field.alias or name
                where = _boolean_number(field.annotation, data.get(key), key)
                if where is not None:
                    raise ValueError(f"{where}: expected a number, got a boolean")
        return data
