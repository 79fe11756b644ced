"""Study files: what a tuning study evaluates, the keys it searches, its objective, sampler and held-out set.

A study evaluates either a sweep's episodes (a task config's keys are searched)::

    sweep: {file: ../sweeps/dock_dumbbell.yaml, episodes: 16, seed: 1000}   # the objective's scenes
    held_out: {episodes: 100, seed: 2000}       # best and base compared on these at the end
    objective: failures_then_p95_error          # failure rate, ties broken by the p95 object error
    space:
      ik.posture_cost: {log: [0.001, 0.1]}
      phases.0.force: {float: [5.0, 20.0]}

or step responses of every joint (a gains file's keys are searched)::

    steps: {gains: ../gains/default.yaml, amplitude_deg: 45, relative: [LEFT_ELBOW, RIGHT_ELBOW]}
    held_out: {amplitude_deg: 30}
    objective: settling_time                    # mean 2 % settling time; steps missing a criterion are penalised
    space:
      joints.LEFT_SHOULDER.kp: {log: [300, 3000], also: [joints.RIGHT_SHOULDER.kp]}

Every problem is a one-line :class:`~nextage_qp.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from nextage_qp.errors import ConfigError
from nextage_qp.io.schema import YamlModel
from nextage_qp.io.yaml_file import read_yaml_mapping, validate

Number = Annotated[float, Field(allow_inf_nan=False)]
OBJECTIVES = {"sweep": ("failures_then_p95_error",), "steps": ("settling_time",)}
SAMPLERS = ("tpe", "cmaes")
PARAM_KEYS = ("float", "log", "int", "choice", "also")


class Param(YamlModel):
    """One searched key and its range.

    Exactly one of ``float: [lo, hi]``, ``log: [lo, hi]`` (lo > 0), ``int: [lo, hi]``, ``choice: [a, b, ...]``;
    ``also`` lists further keys that take the same value (e.g. the other arm's twin joint).
    """

    uniform: tuple[Number, Number] | None = Field(
        default=None, alias="float", description="lo, hi [key's unit]: a value drawn uniformly between them.")
    log: tuple[Number, Number] | None = Field(
        default=None, description="lo, hi [key's unit]: a value drawn log-uniformly between them (lo > 0), for "
                                  "weights and gains spanning decades.")
    integer: tuple[int, int] | None = Field(
        default=None, alias="int", description="lo, hi [key's unit]: an integer between them, both included.")
    choice: list[Any] | None = Field(
        default=None, min_length=1, description="Values to choose from: numbers, strings, booleans or null.")
    also: list[str] = Field(
        default_factory=list, description="Further keys that take the same value (e.g. the other arm's twin joint).")

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, doc: Any) -> Any:  # the names a file writes (float, int), not the fields behind them
        unknown = [k for k in doc if k not in PARAM_KEYS] if isinstance(doc, dict) else []
        if unknown:
            raise ValueError(f"unknown key {unknown[0]!r}; valid: {', '.join(PARAM_KEYS)}")
        return doc

    @model_validator(mode="after")
    def _one_kind(self) -> Param:
        given = [k for k in ("float", "log", "int", "choice") if self.get(k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of float, log, int, choice; got {', '.join(given) or 'none'}")
        bounds = self.bounds
        if bounds is not None and bounds[0] > bounds[1]:
            raise ValueError(f"lo > hi in [{bounds[0]}, {bounds[1]}]")
        if self.log is not None and self.log[0] <= 0:
            raise ValueError(f"log needs lo > 0, got {self.log[0]}")
        for value in self.choice or ():
            if not (value is None or isinstance(value, (bool, int, float, str))):
                raise ValueError("choices must be numbers, strings, booleans or null")
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"choice values must be finite, got {value}")
        return self

    def get(self, kind: str) -> Any:
        """The bounds or choices given under ``kind`` (``float``, ``log``, ``int``, ``choice``)."""
        return {"float": self.uniform, "log": self.log, "int": self.integer, "choice": self.choice}[kind]

    @property
    def kind(self) -> str:
        """``float``, ``log``, ``int`` or ``choice``."""
        return next(k for k in ("float", "log", "int", "choice") if self.get(k) is not None)

    @property
    def bounds(self) -> tuple[float, float] | None:
        """``(lo, hi)``, None for a choice."""
        return self.uniform or self.log or self.integer


class SweepEval(YamlModel):
    """Episodes ``0..episodes-1`` of a sweep file drawn with ``seed``: the objective's scenes."""

    file: str = Field(description="Sweep file, relative to the study file.")
    episodes: int = Field(ge=1, le=100_000, description="Episodes 0..episodes-1 of the sweep, run by every trial "
                                                         "[count].")
    seed: int = Field(default=0, ge=0, lt=2**32,
                      description="Seed the sweep's episodes are drawn with [-] (the same scenes for every trial).")


class StepsEval(YamlModel):
    """Raw steps of every joint from ``home`` to +-``amplitude_deg`` (relative to home for ``relative`` joints)."""

    gains: str = Field(description="Base gains file: a bundled name or a path relative to the study file.")
    amplitude_deg: Number = Field(
        gt=0, le=180, description="Step size [deg]: every joint steps from home to + and - this angle (relative "
                                  "to home for the relative joints).")
    relative: list[str] = Field(
        default_factory=list, description="Joints stepped relative to home (the robot's own body "
                                          "blocks their absolute target).")
    joints: list[str] | None = Field(default=None, description="Joints stepped (default: all 15).")
    duration_s: Number = Field(default=1.0, gt=0, le=30, description="Simulated time of each step run [s].")
    final_error_rad: Number = Field(
        default=0.005, gt=0, description="Largest error from the target at the end of a step that meets the criteria "
                                         "[rad].")
    overshoot_pct: Number = Field(
        default=5.0, ge=0, description="Largest overshoot beyond the target of a step that meets the criteria [%] "
                                       "(of the step's size).")
    scene: str = Field(default="scene", description="Scene the robot steps in: a bundled scene name or an MJCF path "
                                                    "(scene: a floor, nothing else).")


class HeldOut(YamlModel):
    """Where best and base are compared after the search: other sweep episodes, or steps of another amplitude."""

    episodes: int | None = Field(default=None, ge=1, le=100_000,
                                 description="Sweep study: held-out episodes 0..episodes-1 [count].")
    seed: int | None = Field(default=None, ge=0, lt=2**32,
                             description="Sweep study: seed of the held-out episodes [-], not sweep.seed.")
    amplitude_deg: Number | None = Field(default=None, gt=0, le=180,
                                         description="Steps study: step size of the held-out steps [deg].")


class StudyFile(YamlModel):
    """The schema of a study file (see the module docstring)."""

    description: str | None = Field(
        default=None, description="Free text on the study, for the reader (the framework does not use it).")
    sweep: SweepEval | None = Field(
        default=None, description="Evaluate a sweep's episodes, searching keys of its task config (this or steps).")
    steps: StepsEval | None = Field(
        default=None, description="Evaluate joint step responses, searching keys of a gains file (this or sweep).")
    held_out: HeldOut | None = Field(
        default=None, description="Where best and base are compared after the search: other sweep episodes, or "
                                  "steps of another size (unset: no held-out comparison).")
    objective: str | None = Field(
        default=None, description="What the study minimises: failures_then_p95_error (sweep) or settling_time "
                                  "(steps); default: the first of its kind.")
    sampler: Literal["tpe", "cmaes"] = Field(default="tpe", description="Optuna's sampler: TPE or CMA-ES.")
    startup_trials: int = Field(default=10, ge=0, le=10_000,
                                description="Random trials before the sampler models [count].")
    seed: int = Field(default=0, ge=0, lt=2**32, description="Sampler seed [-] (plus the trials already stored, so a "
                                                             "resumed study draws new ones).")
    trials: int = Field(default=30, ge=1, le=100_000, description="Complete trials [count] (default of --trials).")
    workers: int | None = Field(default=None, ge=1, le=1024, description="Parallel tasks (episodes or steps) per "
                                                                        "trial [count] (default of --workers; unset: "
                                                                        "the CPU count).")
    wall_limit: Number | None = Field(
        default=None, gt=0, le=86400,
        description="Wall time after which a sweep episode is stopped and failed [s] (default: the sweep file's; "
                    "steps: 60).")
    space: dict[str, Param] = Field(
        min_length=1, description="Dotted key -> its range: the keys searched (a task config's, or a gains file's).")

    @model_validator(mode="after")
    def _consistent(self) -> StudyFile:
        if (self.sweep is None) == (self.steps is None):
            raise ValueError("give exactly one of 'sweep' (evaluate a sweep's episodes) or 'steps' (step responses)")
        kind = self.kind
        if self.objective is not None and self.objective not in OBJECTIVES[kind]:
            raise ValueError(f"objective {self.objective!r} does not apply to a {kind} study; "
                             f"valid: {', '.join(OBJECTIVES[kind])}")
        held = self.held_out
        if held is not None:
            if kind == "sweep" and (held.amplitude_deg is not None or held.episodes is None or held.seed is None):
                raise ValueError("held_out of a sweep study: give episodes and seed, not amplitude_deg")
            if kind == "sweep" and self.sweep is not None and held.seed == self.sweep.seed:
                raise ValueError(f"held_out.seed {held.seed} is the objective's sweep.seed: held-out episodes "
                                 f"must be other scenes; give another seed")
            if kind == "steps" and (held.amplitude_deg is None or held.episodes is not None or held.seed is not None):
                raise ValueError("held_out of a steps study: give amplitude_deg, not episodes or seed")
        return self

    @property
    def kind(self) -> str:
        """``sweep`` or ``steps``."""
        return "sweep" if self.sweep is not None else "steps"


def read_study(path: str | Path) -> StudyFile:
    """Read and validate a study file's schema.

    Raises:
        ConfigError: Missing file, invalid YAML or a schema violation (one line).
    """
    file = Path(path)
    if file.is_dir():
        raise ConfigError(f"{file}: is a directory; give a study file, e.g. configs/studies/pd_gains.yaml")
    if not file.is_file():
        raise ConfigError(f"{file}: no such study file")
    doc = read_yaml_mapping(file, "a mapping with 'sweep' or 'steps', and 'space'")
    study: StudyFile = validate(StudyFile, doc, str(file))
    for key, param in study.space.items():
        for other in param.also:
            if other == key or other in study.space:
                raise ConfigError(f"{file}: space.{key}.also: {other!r} is searched itself; a key is tied once")
    return study
