"""Schema of a manipulation YAML: scene and overrides, gains, IK, trajectory limits, timing and phases.

Every model forbids unknown keys. The phase list accepts every kind in the phase registry
(:mod:`nextage_qp.manipulation.phases`); :func:`config_model` builds that schema. :func:`load_config` turns any
validation failure into a one-line :class:`~nextage_qp.errors.ConfigError` naming the file, the dotted key, the
bad value and what is valid. Names that depend on the scene (frames, objects, bodies, joints) are checked by the
runner once the scene is loaded, with the same kind of message.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
import yaml
from pydantic import Field, create_model, model_validator

from nextage_qp.errors import ConfigError
from nextage_qp.ik import IKConfig
from nextage_qp.io.schema import YamlModel
from nextage_qp.io.yaml_file import load_yaml, read_yaml_mapping, validate, yaml_error_line
from nextage_qp.loop.reference import TrajectoryLimits
from nextage_qp.loop.simulation import Timing
from nextage_qp.manipulation.phases import REGISTRY, Spec
from nextage_qp.manipulation.phases.base import MAX_SECONDS, name_field
from nextage_qp.planning.rrt import PlanningConfig
from nextage_qp.robots.robot_file import MountFile
from nextage_qp.scene.clutter import ClutterDecl
from nextage_qp.scene.files import package_root
from nextage_qp.scene.objects import ObjectDecl
from nextage_qp.sensing.faults import EstimationConfig, FaultsConfig
from nextage_qp.sensing.perception_config import PerceptionConfig

Vec3 = tuple[float, float, float]


class FreeSpot(YamlModel):
    """A target placed where its object fits: the spot nearest ``near`` in ``region`` clear of every obstacle."""

    region: tuple[tuple[float, float], tuple[float, float]] = Field(
        description="Rectangle [m], [[x0, y0], [x1, y1]], in which the object's origin may be placed.")
    near: tuple[float, float] | None = Field(
        default=None, description="Point [m] the spot is chosen nearest to (unset: the region's centre).")
    clearance: float = Field(default=0.03, ge=0, le=0.09, allow_inf_nan=False,
                             description="Least distance [m] from the object, upright at the spot, to every obstacle "
                                         "beside it (the clutter, fixed objects, the scene's obstacle).")

    @model_validator(mode="after")
    def _finite(self) -> FreeSpot:
        (x0, y0), (x1, y1) = self.region
        if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or not (x0 < x1 and y0 < y1):
            raise ValueError(f"region: [[{x0}, {y0}], [{x1}, {y1}]] must be finite with x0 < x1 and y0 < y1")
        if self.near is not None and not all(math.isfinite(v) for v in self.near):
            raise ValueError(f"near: {list(self.near)} must be finite")
        return self

    def centre(self) -> tuple[float, float]:
        """``near``, or the region's centre."""
        (x0, y0), (x1, y1) = self.region
        return self.near if self.near is not None else (0.5 * (x0 + x1), 0.5 * (y0 + y1))


class PoseOverride(YamlModel):
    """A body's pose in the world: position [m] and yaw about world z [rad] (either may be left out)."""

    pos: Vec3 | None = Field(
        default=None, description="Position in the world [m]: an object's start, a target's or obstacle's fixed "
                                  "place (unset: the scene's; wins over a declared object's pos).")
    yaw: float | None = Field(
        default=None, description="Yaw about world z [rad] (unset: the scene's orientation; wins over a declared "
                                  "object's yaw).")
    free_spot: FreeSpot | None = Field(
        default=None, description="A target's place chosen before the run where its object fits among the obstacles "
                                  "(instead of pos): the spot nearest near in region keeping clearance from them.")

    @model_validator(mode="after")
    def _one_place(self) -> PoseOverride:
        if self.free_spot is not None and self.pos is not None:
            raise ValueError("give pos or free_spot, not both")
        return self


class SceneConfig(YamlModel):
    """Which scene to load and what to change in it without editing XML."""

    file: str = Field(description="Bundled scene name (push_cube, dock_dumbbell) or MJCF path.")
    frame: Literal["world", "workspace"] = Field(
        default="world", description="Frame of the positions below: world, or the robot file's workspace (x-y from "
                                     "the work region's centre, z above the table top; the table stands where the "
                                     "robot file puts it), so that one config serves every robot.")
    poses: dict[str, PoseOverride] = Field(default_factory=dict, description="Body -> start/fixed pose.")
    masses: dict[str, Annotated[float, Field(ge=1e-4, le=50.0)]] = Field(
        default_factory=dict, description="Body -> mass [kg], 0.1 g to 50 kg (as a declared object's).")
    friction_scale: dict[str, Annotated[float, Field(gt=0, le=20.0, allow_inf_nan=False)]] = Field(
        default_factory=dict, description="Body -> factor [1] on the sliding friction of all its contacts "
                                          "(default 1, at most 20).")
    objects: dict[str, ObjectDecl] = Field(
        default_factory=dict, description="Object -> shape, size, mass, friction, pose (nextage_qp/scene/objects.py).")
    clutter: ClutterDecl | None = Field(
        default=None, description="Random boxes and cylinders on the table, named clutter_0 ... (collision group "
                                  "clutter): nextage_qp/scene/clutter.py.")


class SuccessCriteria(YamlModel):
    """What a successful run means.

    Besides these, every run must complete its phases, keep its joints inside their limits and not drop a
    clamped object. The object's yaw is compared with the target's modulo the object's symmetry (declared in the scene).
    """

    planar_error: float = Field(default=0.005, gt=0, le=1.0, description="Largest x-y object error [m].")
    yaw_error: float | None = Field(default=None, gt=0, le=3.2, description="Largest yaw error [rad], or unjudged.")
    tilt: float | None = Field(default=None, gt=0, le=3.2, description="Largest tilt from upright [rad], or unjudged.")
    resting: bool = Field(default=False, description="The object must end on the table, at rest.")
    obstacle_contacts: int | None = Field(
        default=None, ge=0, description="Most physics steps the object may touch the obstacle [count], or unjudged.")
    clutter_contacts: int | None = Field(
        default=None, ge=0, description="Most physics steps [count] in which the robot or what it holds may touch "
                                        "the clutter (scene.clutter), or unjudged.")
    obstacle_clearance: float | None = Field(
        default=None, ge=0, le=0.2, allow_inf_nan=False,
        description="Least distance [m] from the task's object at the end to every obstacle beside it (the clutter, "
                    "fixed objects, the scene's obstacle), or unjudged: a place chosen by free_spot kept.")
    objects: dict[str, str] = Field(
        default_factory=dict, description="Further objects judged against their targets, object -> target body, "
                                          "with the same limits as the task's object (e.g. a two-cube push).")
    knocked: float | None = Field(
        default=0.02, gt=0, le=1.0, allow_inf_nan=False,
        description="Farthest [m] a free object that no phase names (a bystander) may end from where it started, "
                    "or unjudged.")


class RunTiming(Timing):
    """The simulation's timing plus the settling time after the last phase."""

    settle: float = Field(default=0.5, ge=0, le=MAX_SECONDS, description="Simulated time after the last phase [s].")


class ManipulationConfig(YamlModel):
    """A whole manipulation run (the phase list takes any registered kind: see :func:`config_model`)."""

    task: str = Field(description="Name of the run in outputs.")
    robot: str = Field(default="nextage", min_length=1, description="Robot file (bundled name or path).")
    mount: MountFile | None = Field(
        default=None, description="Where the robot's own frame stands in the scene (default: the robot file's "
                                  "mount): a mobile robot's start pose.")
    scene: SceneConfig = Field(
        description="Which scene to load and what to change in it without editing XML: body poses, masses, friction, "
                    "declared objects.")
    object: str = name_field("object", description="Body whose final error is reported.")
    target: str = name_field("place", description="Body marking the object's target.")
    start: str | dict[str, float] = Field(
        default="home", description="Start pose [rad]: a keyframe of the robot file (home, zero, ...), or joint -> "
                                    "angle, the other joints at home.")
    success: SuccessCriteria = Field(default_factory=SuccessCriteria, description="Success criteria.")
    gains: str | None = Field(
        default=None,
        description=(
            "Gains file (a bundled name in the robot file's gains folder, or a path); none: the robot file's gains."
        ),
    )
    ik: IKConfig = Field(
        default_factory=IKConfig, description="The QP inverse kinematics: task costs, damping, joint and collision "
                                              "limits, solver, and the settings of the offline solve().")
    trajectory: TrajectoryLimits = Field(
        default_factory=TrajectoryLimits, description="Ruckig's bounds on the joint references: velocity, "
                                                      "acceleration and jerk, one value or per joint.")
    timing: RunTiming = Field(
        default_factory=RunTiming, description="Physics step, control period, and simulated time after the last "
                                               "phase.")
    seed: int = Field(default=0, ge=0, description="Seed of the run's own random draws [-] (a sweep sets one per "
                                                   "episode; all fault noise derives from it).")
    faults: FaultsConfig | None = Field(default=None, description="Sensor faults and shoves (none: perfect sensors).")
    estimation: EstimationConfig = Field(
        default_factory=EstimationConfig, description="How object measurements become the poses the phases see "
                                                      "(a Kalman filter or the latest measurement).")
    planning: PlanningConfig = Field(
        default_factory=PlanningConfig, description="How transits are planned around obstacles: the clearance kept "
                                                    "and the time a plan may take.")
    perception: PerceptionConfig = Field(
        default_factory=PerceptionConfig, description="Where the object poses the phases see come from: the "
                                                      "simulator's truth, the simulated camera of "
                                                      "faults.object_pose, or the robot's own camera.")
    phases: list[Spec] = Field(min_length=1)

    @model_validator(mode="after")
    def _target_is_another_body(self) -> ManipulationConfig:
        if self.target == self.object:
            raise ValueError(f"target: {self.object!r} is the object itself (its error to itself is always 0); "
                             "name the body that marks its target")
        return self

    @model_validator(mode="after")
    def _phase_names_are_unique(self) -> ManipulationConfig:
        seen: dict[str, int] = {}
        for i, phase in enumerate(self.phases):
            if phase.name is not None and phase.name in seen:
                raise ValueError(f"phases[{i}].name: {phase.name!r} is also phases[{seen[phase.name]}]'s name; a "
                                 "failure names its phase, so give each phase its own")
            if phase.name is not None:
                seen[phase.name] = i
        return self

    @model_validator(mode="after")
    def _grips_come_first(self) -> ManipulationConfig:
        held: str | None = None
        for i, phase in enumerate(self.phases):
            obj = getattr(phase, "object", None)
            if phase.grip in ("needs", "ends") and obj != held:
                raise ValueError(f"phases[{i}]: {phase.kind} needs {obj!r} clamped by an earlier grasp phase"
                                 f"{f' (the clamp holds {held!r} then)' if held else ''}")
            if phase.grip == "makes":
                held = obj
            elif phase.grip == "ends":
                held = None
        return self

    def phase_name(self, index: int) -> str:
        """The phase's name, or ``kind[index]`` when it has none."""
        phase: Any = self.phases[index]
        return phase.name or f"{phase.kind}[{index}]"


_models: dict[tuple[tuple[str, type[Spec]], ...], type[ManipulationConfig]] = {}


def config_model() -> type[ManipulationConfig]:
    """:class:`ManipulationConfig` with its phase list typed as the union of every registered kind."""
    key = tuple((kind, spec) for kind, (spec, _) in REGISTRY.items())
    if key not in _models:
        specs = tuple(spec for _, spec in key)
        union: Any = specs[0] if len(specs) == 1 else Annotated[Union[specs], Field(discriminator="kind")]  # noqa: UP007
        _models[key] = create_model("ManipulationConfig", __base__=ManipulationConfig,
                                    phases=(list[union], Field(min_length=1)))
    return _models[key]


def apply_override(doc: dict[str, Any], assignment: str, source: str = "--set") -> None:
    """Apply one ``dotted.key=value`` override (value parsed as YAML; list items by index) in place.

    A list item is addressed as ``phases.0.timeout`` or ``phases[0].timeout``.

    Raises:
        ConfigError: Malformed assignment or a path through something that is not a mapping or list.
    """
    key, sep, raw = assignment.partition("=")
    if not sep or not key:
        example = "scene.poses.cube.pos=[0.35,0,0.91]"
        raise ConfigError(f"{source} {assignment!r}: expected dotted.key=value, e.g. {example}")
    try:
        value = load_yaml(raw)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source} {assignment!r}: the value is not valid YAML: {yaml_error_line(exc)}; "
                          "quote strings, write lists as [a, b]") from None
    parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
    node: Any = doc
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        where = ".".join(parts[: i + 1])
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise ConfigError(f"{source} {key}: {where!r} needs a list index below {len(node)}")
            if last:
                node[int(part)] = value
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise ConfigError(f"{source} {key}: {'.'.join(parts[:i])!r} is a value, not a mapping or list")


def config_file(path: str | Path) -> Path:
    """A config given as a path or a bundled name (``push_cube``, ``dock_dumbbell``).

    Raises:
        ConfigError: A directory, or neither a file nor a bundled name (the message lists the bundled configs).
    """
    file = Path(path)
    if file.is_file():
        return file
    if file.is_dir():
        raise ConfigError(f"{file}: is a directory; give a config file, e.g. configs/push_cube.yaml")
    bundled = package_root() / "configs"
    for cand in (bundled / file, bundled / f"{file}.yaml"):
        if cand.is_file() and len(file.parts) == 1:
            return cand
    names = sorted(p.stem for p in bundled.glob("*.yaml"))
    raise ConfigError(f"{file}: no such config file; bundled: {', '.join(names)} (or a path to a YAML file)")


def _relative_to(doc: dict[str, Any], folder: Path) -> None:
    """Make the file paths a config names (``gains``, ``robot``, ``scene.file``) relative to its own folder, in place.

    A value that names an existing file next to the config becomes that file's path; anything else (a bundled
    name, an absolute path) is left for the loaders to resolve.
    """
    scene = doc.get("scene")
    holders: list[tuple[dict[str, Any], str]] = [(doc, "gains"), (doc, "robot")]
    if isinstance(scene, dict):
        holders.append((scene, "file"))
    for holder, key in holders:
        value = holder.get(key)
        if isinstance(value, str) and value and not Path(value).is_absolute() and (folder / value).is_file():
            holder[key] = str(folder / value)


def load_config(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> ManipulationConfig:
    """Read, override and validate a manipulation YAML.

    Raises:
        ConfigError: Missing file, invalid YAML, a bad override or a schema violation (one line each).
    """
    file = config_file(path)
    doc = read_yaml_mapping(file, "a mapping at the top level")
    _relative_to(doc, file.parent)
    for assignment in overrides:
        apply_override(doc, assignment)
    return validate(config_model(), doc, str(file))


def jitter_overrides(path: str | Path, seed: int, base: list[str]) -> list[str]:
    """``base`` plus overrides that shift the object's start and its target by a seeded random offset.

    The offset is at most 2 cm in x and y and 10 deg of yaw (``nextage-qp run --seed``).
    """
    cfg = load_config(path, base)
    rng = np.random.default_rng(seed)
    out = list(base)
    for body in (cfg.object, cfg.target):
        pose = cfg.scene.poses.get(body)
        if pose is None or pose.pos is None:
            continue
        dx, dy = rng.uniform(-0.02, 0.02, 2)
        yaw = (pose.yaw or 0.0) + float(rng.uniform(-np.pi / 18, np.pi / 18))
        x, y, z = pose.pos
        out += [f"scene.poses.{body}.pos=[{x + dx:.4f},{y + dy:.4f},{z}]", f"scene.poses.{body}.yaw={yaw:.4f}"]
    if len(out) == len(base):
        raise ConfigError(f"{path}: --seed shifts the start of the object and the target, but scene.poses gives "
                          f"neither {cfg.object!r} nor {cfg.target!r} a pos; add one or drop --seed")
    return out
