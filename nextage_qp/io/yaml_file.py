"""YAML files in, one-line errors out.

Reading a mapping, and turning a pydantic failure into a message that names the file, the dotted key, what is wrong, the
bad value and what would be valid.
"""

from __future__ import annotations

import re
import typing
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from nextage_qp.errors import ConfigError, one_line

STRICT = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
"""The ``model_config`` of every schema read from YAML: unknown keys are errors, values are immutable, and no
float may be NaN or infinite (``.inf`` / ``.nan`` are valid YAML, never a valid setting)."""


class StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 scalars and no silent surprises.

    * Booleans are only ``true`` / ``false`` (YAML 1.1's ``yes``, ``no``, ``on``, ``off`` stay strings, so
      ``settle: yes`` is refused where a number is expected instead of read as 1.0).
    * Floats include ``1e-5`` (YAML 1.1 needs a dot and reads it as a string).
    * A key given twice in one mapping is an error (PyYAML keeps the last one silently).
    """


StrictLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in ("tag:yaml.org,2002:bool", "tag:yaml.org,2002:float")]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
StrictLoader.add_implicit_resolver("tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"),
                                   list("tTfF"))
StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."),
)


def _mapping_without_duplicates(loader: StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
    seen: dict[Any, int] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"key {key!r} appears twice in one mapping (lines {seen[key] + 1} and "
                f"{key_node.start_mark.line + 1}); give it once", key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=deep)


StrictLoader.add_constructor("tag:yaml.org,2002:map", _mapping_without_duplicates)


def load_yaml(text: str) -> Any:
    """Parse YAML text with :class:`StrictLoader` (raises ``yaml.YAMLError``)."""
    return yaml.load(text, Loader=StrictLoader)  # a SafeLoader subclass: no arbitrary objects


def yaml_error_line(exc: yaml.YAMLError) -> str:
    """A YAML error as one line: the problem and where (line, column)."""
    problem, mark = getattr(exc, "problem", None), getattr(exc, "problem_mark", None)
    if problem and mark is not None:
        context = getattr(exc, "context", None)
        return f"{context + ': ' if context else ''}{problem} (line {mark.line + 1}, column {mark.column + 1})"
    return one_line(exc)


def read_text_file(file: Path) -> str:
    """The UTF-8 text of ``file``.

    Raises:
        ConfigError: Not a readable file (missing, a directory, no permission) or not UTF-8 text.
    """
    if file.is_dir():
        raise ConfigError(f"{file}: is a directory, not a file")
    try:
        raw = file.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{file}: cannot read: {exc.strerror}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{file}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); "
                          "expected a YAML text file") from None
    if "\x00" in text:
        raise ConfigError(f"{file}: binary data (a NUL byte at offset {text.index(chr(0))}); expected a YAML text file")
    return text


def read_yaml_mapping(file: Path, expected: str) -> dict[str, Any]:
    """The mapping at the top of ``file``.

    Args:
        file: The YAML file.
        expected: What the top level should be, for the error message (e.g. "a mapping at the top level").

    Raises:
        ConfigError: The file cannot be read, is not UTF-8 text, is not valid YAML (duplicate keys included),
            or its top level is not a mapping.
    """
    text = read_text_file(file)
    try:
        doc = load_yaml(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{file}: not valid YAML: {yaml_error_line(exc)}") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"{file}: expected {expected}")
    return doc


def validate(model: type[BaseModel], doc: Any, source: str) -> Any:
    """``model.model_validate(doc)``, with a failure turned into a one-line :class:`ConfigError`."""
    try:
        return model.model_validate(doc)
    except ValidationError as exc:
        raise ConfigError(format_validation_error(source, exc, model)) from None


def format_validation_error(source: str, exc: ValidationError, root: type[BaseModel]) -> str:
    """One line: ``source: dotted.key: message (got value)`` for the first error, plus a count of the rest.

    An unknown key lists the keys valid at its level; an unknown tag of a tagged union (e.g. a phase ``kind``)
    lists the valid tags.
    """
    errors = exc.errors()
    first, errors = _union_branch(errors, _model_names(root))
    loc = tuple(first["loc"])
    key = _dotted(root, loc) or "<top level>"
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] == "missing":
        msg = "required, but missing"
    elif first["type"] == "extra_forbidden":
        msg = f"unknown key; valid: {', '.join(valid_keys(root, loc[:-1]))}"
    elif first["type"] == "union_tag_not_found":  # e.g. a phase without its ``kind``
        field = str(first.get("ctx", {}).get("discriminator", "kind")).strip("'")
        kinds = [t for m in _walk(root, loc)[0] if (t := _tag(m)) is not None]
        key = f"{key}.{field}"
        msg = f"missing; valid: {', '.join(kinds)}" if kinds else "missing"
    elif first["type"] == "union_tag_invalid":
        tags = str(first.get("ctx", {}).get("expected_tags", "")).replace("'", "")
        msg = f"unknown {first.get('ctx', {}).get('discriminator', 'kind').strip(chr(39))}; valid: {tags}"
    got = first.get("input")
    quiet = ("missing", "extra_forbidden", "union_tag_not_found")
    shown = "" if first["type"] in quiet or isinstance(got, dict) else f" (got {got!r})"
    more = f" (and {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''})" if len(errors) > 1 else ""
    if not loc and re.match(r"[\w.\[\]]+: ", msg):  # a check across keys that names its own key
        return f"{source}: {msg}{shown}{more}"
    return f"{source}: {key}: {msg}{shown}{more}"


UNION_MEMBER = re.compile(r"(str|int|float|bool|none|constrained-\w+|(literal|dict|list|tuple|function-\w+)\[.*\])")
"""How pydantic names a member of a plain union in an error's location (``start.dict[str,float].JOINT``)."""


def _model_names(root: type[BaseModel]) -> set[str]:
    """Names of every model reachable from ``root`` (pydantic names a union's model member by its class)."""
    seen: dict[str, type[BaseModel]] = {}
    todo = [root]
    while todo:
        model = todo.pop()
        if model.__name__ not in seen:
            seen[model.__name__] = model
            todo += [m for f in model.model_fields.values() for m in _models_in(f.annotation)]
    return set(seen)


def _member(part: Any, models: set[str]) -> bool:
    return isinstance(part, str) and (part in models or UNION_MEMBER.fullmatch(part) is not None)


def _union_branch(errors: list[Any], models: set[str]) -> tuple[Any, list[Any]]:
    """The error to report, and the problems counted beside it.

    A value that fits no member of a union fails once per member. The member that got furthest into the value is
    the one meant (``start: {JOINT: .nan}`` is a mapping with a bad number, not a bad string); where none got
    further than the others, their messages are joined: each says what would be valid.
    """
    def plain(loc: Any) -> tuple[Any, ...]:  # the location without the names of union members
        return tuple(p for p in loc if not _member(p, models))

    first = errors[0]
    cut = next((i for i, p in enumerate(first["loc"]) if _member(p, models)), None)
    if cut is None:
        return first, errors
    prefix = tuple(first["loc"][:cut])
    branch = [e for e in errors if tuple(e["loc"][:cut]) == prefix]
    rest = [e for e in errors if tuple(e["loc"][:cut]) != prefix]
    best = max(branch, key=lambda e: len(plain(e["loc"])))  # the first of the deepest
    same = [e for e in branch if plain(e["loc"]) == plain(best["loc"])]
    msg = "; or ".join(dict.fromkeys(e["msg"].removeprefix("Value error, ") for e in same))
    return {**best, "loc": plain(best["loc"]), "msg": msg}, [best, *rest]


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def _tag(model: type[BaseModel]) -> str | None:
    field = model.model_fields.get("kind")
    args = typing.get_args(field.annotation) if field is not None else ()
    return str(args[0]) if len(args) == 1 else None


def _walk(root: type[BaseModel], loc: tuple[int | str, ...]) -> tuple[list[type[BaseModel]], list[str]]:
    """The models valid after ``loc`` and the parts of ``loc`` a reader should see (union tags left out)."""
    candidates: list[type[BaseModel]] = [root]
    shown: list[str] = []
    user_key = False
    for part in loc:
        if isinstance(part, int):
            shown.append(f"[{part}]")
            continue
        if user_key:  # a key of a dict field, e.g. the body name in scene.poses
            user_key = False
            shown.append(str(part))
            continue
        tagged = [m for m in candidates if _tag(m) == part]
        if tagged and len(candidates) > 1:
            candidates = tagged
            continue
        shown.append(str(part))
        model = next((m for m in candidates if part in m.model_fields), None)
        if model is None:
            candidates = []
            continue
        annotation = model.model_fields[part].annotation
        user_key = typing.get_origin(annotation) is dict or any(
            typing.get_origin(a) is dict for a in typing.get_args(annotation))
        candidates = _models_in(annotation)
    return candidates, shown


def _dotted(root: type[BaseModel], loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in _walk(root, loc)[1]:
        out += part if part.startswith("[") or not out else f".{part}"
    return out


def valid_keys(root: type[BaseModel], loc: tuple[int | str, ...]) -> list[str]:
    """Keys accepted at a location of a model (for 'unknown key' messages)."""
    candidates = _walk(root, loc)[0]
    return sorted(candidates[0].model_fields) if len(candidates) == 1 else []


NameKind = Literal["frame", "object", "body", "place", "reference", "joint"]
"""What a name field refers to: a site or body of the robot (``frame``), a free object, any body, a body no robot
joint moves (``place``: where an object goes, e.g. a target marker or another object), a body or ``world``
(``reference``), or a robot joint (the keys of a mapping)."""

MAX_SECONDS = 3600.0
"""Upper bound of every duration in a config [s]: a run always has a bounded length."""


def name_field(kind: NameKind, *args: Any, **kwargs: Any) -> Any:
    """A pydantic ``Field`` whose names are checked against the scene's names of ``kind``.

    The value may be a name, a list of names or a mapping keyed by names.
    """
    return Field(*args, json_schema_extra={"names": kind}, **kwargs)
