"""Sweep files: a task config and the distributions its keys are drawn from, validated against that config.

A sweep file names its task config (``base``, relative to the sweep file) and maps dotted keys, the same
keys ``nextage-qp run --set`` accepts, to one distribution each::

    base: ../push_cube.yaml
    wall_limit: 300                                  # [s] per episode
    randomize:
      scene.poses.cube.pos: {offset: [[-0.05, -0.05, 0.0], [0.05, 0.05, 0.0]]}  # added, per component
      scene.poses.cube.yaw: {offset: [-0.5236, 0.5236]}
      scene.masses.cube: {uniform: [0.05, 0.30]}      # absolute value
      scene.friction_scale.cube: {scale: [0.5, 2.0]}  # multiplies the base value
      gains: {choice: [default, report]}

Every problem (an unknown key, a key the base config does not have, ``lo > hi``, NaN or inf, a drawn value
the config rejects) is a one-line :class:`~nextage_qp.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field, field_validator, model_validator

from nextage_qp.errors import ConfigError, InfeasibleError
from nextage_qp.io.schema import YamlModel
from nextage_qp.io.yaml_file import read_yaml_mapping, validate
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import build_robot
from nextage_qp.robots.description import DEFAULT_ROBOT
from nextage_qp.sweep.keys import key_hash, lookup, scene_default, yaml_scalar
from nextage_qp.sweep.nested import check_nested, draw_nested, extremes

Number = Annotated[float, Field(allow_inf_nan=False)]
Bound = Number | list[Number]


class Distribution(YamlModel):
    """One distribution of a randomised key.

    Exactly one of: ``uniform: [lo, hi]`` (absolute), ``offset: [lo, hi]`` (added to the base value),
    ``scale: [lo, hi]`` (multiplies the base value), ``choice: [a, b, ...]``. ``lo`` and ``hi`` are numbers,
    or lists of numbers for a vector key (drawn per component).
    """

    uniform: tuple[Bound, Bound] | None = Field(
        default=None, description="lo, hi [key's unit]: the value, drawn uniformly between them (numbers, or lists "
                                  "of numbers for a vector key, drawn per component).")
    offset: tuple[Bound, Bound] | None = Field(
        default=None, description="lo, hi [key's unit]: added to the base config's value, drawn uniformly between "
                                  "them (per component for a vector key).")
    scale: tuple[Bound, Bound] | None = Field(
        default=None, description="lo, hi [1]: a factor on the base config's value, drawn uniformly between them "
                                  "(per component for a vector key).")
    choice: list[Any] | None = Field(
        default=None, min_length=1, description="Values, one of them drawn with equal chance (any YAML value, which "
                                                "may hold nested uniform or choice distributions).")

    @model_validator(mode="after")
    def _one_kind(self) -> Distribution:
        given = [k for k in ("uniform", "offset", "scale", "choice") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of uniform, offset, scale, choice; got {', '.join(given) or 'none'}")
        if self.bounds is not None:
            lo, hi = (np.atleast_1d(np.asarray(b, dtype=float)) for b in self.bounds)
            if lo.shape != hi.shape:
                raise ValueError(f"lo and hi must have the same length, got {lo.tolist()} and {hi.tolist()}")
            if np.any(lo > hi):
                raise ValueError(f"lo > hi in [{self.bounds[0]}, {self.bounds[1]}]")
        for value in self.choice or ():
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"choice values must be finite, got {value}")
            check_nested(value)
        return self

    @property
    def kind(self) -> str:
        """``uniform``, ``offset``, ``scale`` or ``choice``."""
        return next(k for k in ("uniform", "offset", "scale", "choice") if getattr(self, k) is not None)

    @property
    def bounds(self) -> tuple[Bound, Bound] | None:
        """``(lo, hi)`` of a uniform, offset or scale distribution; None for a choice."""
        return self.uniform or self.offset or self.scale

    def draw(self, rng: np.random.Generator, base: Any) -> Any:
        """One value: a float, a list of floats, or one of the choices."""
        if self.choice is not None:  # a choice may hold nested distributions (nextage_qp/sweep/nested.py)
            return draw_nested(self.choice[int(rng.integers(len(self.choice)))], rng)
        lo, hi = (np.asarray(b, dtype=float) for b in self.bounds or (0.0, 0.0))
        u = lo + (hi - lo) * rng.random(lo.shape)
        if self.offset is not None:
            u = np.asarray(base, dtype=float) + u
        elif self.scale is not None:
            u = np.asarray(base, dtype=float) * u
        return u.tolist() if u.ndim else float(u)


def _flow(value: Any) -> str:
    """A YAML flow literal of a ``set:`` value (mappings and lists as JSON, which YAML reads back as they were)."""
    if isinstance(value, (dict, list)):
        return json.dumps(value, allow_nan=False)
    return yaml_scalar(value)


class SweepFile(YamlModel):
    """The schema of a sweep file (see the module docstring)."""

    base: str = Field(description="Task config, relative to the sweep file.")
    description: str | None = Field(
        default=None, description="Free text on what the sweep draws, for the reader (the framework does not use it).")
    wall_limit: float = Field(default=300.0, gt=0, le=86400, allow_inf_nan=False,
                              description="Wall time after which an episode is stopped and failed [s].")
    set: dict[str, Any] = Field(default_factory=dict,
                                description="Dotted key -> value applied to the base config in every episode.")
    randomize: dict[str, Distribution] = Field(
        min_length=1, description="Dotted key (as run --set takes) -> the distribution each episode draws it from; a "
                                  "list is a choice of that one list.")

    @field_validator("randomize", mode="before")
    @classmethod
    def _lists_hold_distributions(cls, value: Any) -> Any:
        """A list with nested distributions in it (``[{uniform: [lo, hi]}, 0.12]``) is a choice of that one list."""
        if isinstance(value, dict):
            return {k: {"choice": [v]} if isinstance(v, list) else v for k, v in value.items()}
        return value


def _fails(path: Path) -> bool:
    """Whether a config fails to load on its own."""
    try:
        load_config(path)
    except ConfigError:
        return True
    return False


class SweepSpec:
    """A validated sweep: the file, its base config, the distributions and the base value of every key.

    Args:
        path: The sweep YAML.
        extra: ``KEY=VALUE`` overrides applied to every episode after the file's own ``set:`` (the command's
            ``--set``); a key the sweep randomises cannot be set.

    Raises:
        ConfigError: Any problem with the file, its base config or a key (one line naming file and key).
    """

    def __init__(self, path: str | Path, extra: Sequence[str] = ()) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise ConfigError(f"{self.path}: no such sweep file")
        doc = read_yaml_mapping(self.path, "a mapping with keys 'base' and 'randomize'")
        if "base" not in doc and "phases" in doc:
            raise ConfigError(f"{self.path}: this is a task config (it has phases), not a sweep file: give a sweep "
                              "file (base: TASK.yaml, randomize: ...; e.g. configs/sweeps/push_cube.yaml), or run "
                              "the task with nextage-qp run")
        self.file = validate(SweepFile, doc, str(self.path))
        self.base_path = (self.path.parent / self.file.base).resolve()
        if not self.base_path.is_file():
            raise ConfigError(f"{self.path}: base: {self.file.base!r} is not a file (resolved to {self.base_path})")
        self.fixed = [f"{key}={_flow(value)}" for key, value in self.file.set.items()]
        try:
            self.base = load_config(self.base_path, self.fixed)
        except ConfigError as exc:  # the base config itself (it fails alone too), or a key of the sweep's own set:
            where = "base" if not self.fixed or _fails(self.base_path) else "set"
            raise ConfigError(f"{self.path}: {where}: {exc}") from None
        self.extra = list(extra)
        self.distributions = dict(self.file.randomize)
        if self.extra:
            for item in self.extra:
                key = item.split("=", 1)[0].strip()
                clash = [k for k in self.distributions if k == key or k.startswith(key + ".")]
                if clash:
                    raise ConfigError(f"--set {item}: the sweep randomises {', '.join(clash)}; set a key it does "
                                      "not randomise")
            try:
                self.base = load_config(self.base_path, [*self.fixed, *self.extra])
            except ConfigError as exc:
                raise ConfigError(f"--set: {exc}") from None
            self.fixed += self.extra
        if "seed" in self.distributions:
            raise self._fail("seed", "the sweep sets each episode's run seed itself; remove this key")
        robot = build_robot(self.base, str(self.base_path))
        self.base_values = {key: self._base_value(key, robot) for key in self.distributions}
        self._check_draws()

    @property
    def name(self) -> str:
        """The sweep file's stem (``push_cube``), after the robot's name for other robots (``yumi-push_cube``)."""
        robot = Path(str(self.base.robot)).stem
        return self.path.stem if robot == DEFAULT_ROBOT else f"{robot}-{self.path.stem}"

    @property
    def wall_limit(self) -> float:
        """Per-episode wall-time limit [s]."""
        return self.file.wall_limit

    def _fail(self, key: str, message: str) -> ConfigError:
        return ConfigError(f"{self.path}: randomize.{key}: {message}")

    def _base_value(self, key: str, robot: Any) -> Any:
        """The key's value in the base config, or the scene's own value for a scene override left unset."""
        value = lookup(self.base, key.split("."), lambda msg: self._fail(key, msg))
        if value is None:
            value = scene_default(robot, key)
        dist = self.distributions[key]
        if dist.kind in ("offset", "scale"):
            if value is None:
                raise self._fail(key, f"{dist.kind} needs a base value, and the base config sets none; use uniform")
            try:
                base = np.atleast_1d(np.asarray(value, dtype=float))
            except (TypeError, ValueError):
                raise self._fail(key, f"{dist.kind} needs a numeric base value, got {value!r}; use choice") from None
            lo = np.atleast_1d(np.asarray(dist.bounds[0] if dist.bounds else 0.0, dtype=float))
            if base.shape != lo.shape:
                raise self._fail(key, f"bounds have {lo.size} component(s) but the base value {value} has {base.size}")
        return value

    def _check_draws(self) -> None:
        """Validate the config at every key's extremes, and build a run for every choice and for episode 0.

        Building the run (scene, names, gains, IK, simulation) catches what the schema cannot: an unknown body,
        a gains file that does not exist. Problems a scene shows only at run time are the episode's own.
        """
        for key, dist in self.distributions.items():
            values = ([v for c in dist.choice for v in extremes(c)] if dist.choice is not None
                      else [self.value_at(key, b) for b in dist.bounds or ()])
            for value in values:
                try:
                    cfg = load_config(self.base_path, [*self.fixed, f"{key}={yaml_scalar(value)}"])
                    if dist.choice is not None:
                        self._build(cfg)
                except ConfigError as exc:
                    raise self._fail(key, f"value {yaml_scalar(value)}: {exc}") from None
        params, run_seed = self.draw(0, 0)
        try:
            self._build(load_config(self.base_path, self.overrides(params, run_seed)))
        except ConfigError as exc:
            raise ConfigError(f"{self.path}: randomize: {exc}") from None

    def _build(self, cfg: Any) -> None:
        """Build a run of ``cfg`` (scene, names, gains, IK); a scene it cannot do is an episode's own outcome."""
        from nextage_qp.manipulation.runner import Runner

        try:
            Runner(cfg, str(self.base_path))
        except InfeasibleError:
            pass

    def value_at(self, key: str, bound: Bound) -> Any:
        """The value of ``key`` at one bound of its distribution (base value applied for offset and scale)."""
        dist, base = self.distributions[key], self.base_values[key]
        b = np.asarray(bound, dtype=float)
        if dist.offset is not None:
            b = np.asarray(base, dtype=float) + b
        elif dist.scale is not None:
            b = np.asarray(base, dtype=float) * b
        return b.tolist() if b.ndim else float(b)

    def draw(self, seed: int, index: int) -> tuple[dict[str, Any], int]:
        """Episode ``index`` of the sweep seeded ``seed``: its parameters (key -> value) and its run seed.

        Each key has its own stream, seeded by (seed, index, key), so episodes and keys are independent of the
        order they are drawn in and of each other.
        """
        params = {}
        for key, dist in self.distributions.items():
            rng = np.random.default_rng([seed, index, key_hash(key)])
            params[key] = dist.draw(rng, self.base_values[key])
        run_seed = int(np.random.SeedSequence([seed, index]).generate_state(1)[0] >> 1)
        return params, run_seed

    def overrides(self, params: dict[str, Any], run_seed: int) -> list[str]:
        """``--set`` strings that turn the base config into the episode's config (exact round trip)."""
        return [*self.fixed, *(f"{key}={yaml_scalar(value)}" for key, value in params.items()), f"seed={run_seed}"]
