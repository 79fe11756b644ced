"""Dotted config keys of a sweep: where they lead in a config, their scene defaults, and exact YAML literals."""

from __future__ import annotations

import json
import zlib
from typing import Any

import numpy as np
import yaml
from pydantic import BaseModel

from nextage_qp.io.yaml_file import load_yaml


def yaml_scalar(value: Any) -> str:
    """A YAML flow literal that reads back as exactly ``value`` (floats keep every bit)."""
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "null"}[value]
    if isinstance(value, float):
        text = repr(value)
        mantissa, e, exponent = text.partition("e")
        if e and "." not in mantissa:  # YAML 1.1 reads 1e-05 as a string; 1.0e-05 is a float
            text = f"{mantissa}.0e{exponent}"
        return text
    if isinstance(value, int):
        return str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(yaml_scalar(v) for v in value) + "]"
    if isinstance(value, dict):  # a flow mapping, e.g. a drawn object declaration
        return "{" + ",".join(f"{yaml_scalar(str(k))}: {yaml_scalar(v)}" for k, v in value.items()) + "}"
    if isinstance(value, str):
        try:
            plain = load_yaml(value) == value and "," not in value and "]" not in value  # as --set reads it
        except yaml.YAMLError:
            plain = False
        return value if plain else json.dumps(value)  # a JSON string is a double-quoted YAML scalar
    raise TypeError(f"cannot write {value!r} as a YAML scalar")


def key_hash(key: str) -> int:
    """A stable 32-bit hash of a key (seeds its random stream)."""
    return zlib.crc32(key.encode())


def lookup(node: Any, parts: list[str], fail: Any) -> Any:
    """Walk a validated config along ``parts``; dict fields take any key (its value None when absent)."""
    for i, part in enumerate(parts):
        where = ".".join(parts[: i + 1])
        if isinstance(node, BaseModel):
            fields = type(node).model_fields
            if part not in fields:
                raise fail(f"{where!r} is not a key of the base config; valid here: {', '.join(sorted(fields))}")
            node = getattr(node, part)
        elif isinstance(node, (list, tuple)):
            if not part.isdigit() or int(part) >= len(node):
                raise fail(f"{where!r}: the base config's list has {len(node)} item(s); use an index below that")
            node = node[int(part)]
        elif isinstance(node, dict):
            node = node.get(part)
            if node is None:
                return None  # e.g. scene.masses.cube when the base config sets no mass: a new dict key
        elif node is None:
            return None
        else:
            raise fail(f"{'.'.join(parts[:i])!r} is a value ({node!r}), not a mapping or list")
    return node.model_dump() if isinstance(node, BaseModel) else node


def scene_default(robot: Any, key: str) -> Any:
    """What the scene itself sets for a scene override key the config leaves unset (None if nothing)."""
    parts = key.split(".")
    if len(parts) < 3 or parts[0] != "scene":
        return None
    kind, body = parts[1], parts[2]
    if body not in robot.body_names:
        return None
    model_body = robot.model.body(body)
    if kind == "masses":
        return float(model_body.mass[0])
    if kind == "friction_scale":
        return 1.0
    if kind == "poses" and len(parts) == 4 and parts[3] == "pos":
        return [float(v) for v in model_body.pos]
    if kind == "poses" and len(parts) == 4 and parts[3] == "yaw":
        w, _, _, z = model_body.quat
        return float(2.0 * np.arctan2(z, w))
    return None
