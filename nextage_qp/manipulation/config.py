"""Schema of a manipulation YAML: scene and overrides, gains, IK, trajectory limits, timing and phases.

Every model forbids unknown keys. :func:`load_config` turns any validation failure into a one-line
:class:`~nextage_qp.errors.ConfigError` naming the file, the dotted key, the bad value and what is valid.
Names that depend on the scene (frames, objects, geom groups) are checked by the runner once the scene
is loaded, with the same kind of message.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from nextage_qp.errors import ConfigError
from nextage_qp.ik import IKConfig
from nextage_qp.trajectory import TrajectoryLimits
from nextage_qp.yaml_file import read_yaml_mapping

Vec3 = tuple[float, float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PoseOverride(_Strict):
    """A body's pose in the world: position [m] and yaw about world z [rad] (either may be left out)."""

    pos: Vec3 | None = None
    yaw: float | None = None


class SceneConfig(_Strict):
    """Which scene to load and what to change in it without editing XML."""

    file: str = Field(description="Bundled scene name (push_cube, dock_dumbbell) or MJCF path.")
    poses: dict[str, PoseOverride] = Field(default_factory=dict, description="Body -> start/fixed pose.")
    masses: dict[str, Annotated[float, Field(gt=0)]] = Field(default_factory=dict, description="Body -> mass [kg].")
    friction_scale: dict[str, Annotated[float, Field(gt=0, allow_inf_nan=False)]] = Field(
        default_factory=dict, description="Body -> factor on the sliding friction of all its contacts (default 1)."
    )


class TimingConfig(_Strict):
    """Loop rates and the final settling time."""

    sim_dt: float = Field(default=0.001, gt=0, le=0.01, description="Physics step [s].")
    ctrl_dt: float = Field(default=0.004, gt=0, le=0.05, description="IK + Ruckig period [s] (multiple of sim_dt).")
    settle: float = Field(default=0.5, ge=0, description="Simulated time after the last phase [s].")

    @model_validator(mode="after")
    def _multiple(self) -> TimingConfig:
        ratio = self.ctrl_dt / self.sim_dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"ctrl_dt ({self.ctrl_dt} s) must be a whole multiple of sim_dt ({self.sim_dt} s)")
        return self


class TargetSpec(_Strict):
    """Where one tool frame should go, in the world or relative to a named body's live pose.

    The target position is ``ref.pos + R_ref @ offset`` where ``R_ref`` is the reference body's yaw
    (``axes: yaw``) or the identity (``axes: world``). The orientation is either ``yaw`` (the frame's axes
    = the reference yaw turned by ``yaw`` [rad] about world z, z up), a world ``quat`` (w, x, y, z), or a
    tool ``axis`` (frame coordinates) that must point along a world ``direction``; or none.
    """

    frame: str = Field(description="Site or body to move, e.g. left_tool.")
    relative_to: str = Field(default="world", description="'world' or a body name (object, target, obstacle).")
    offset: Vec3 = Field(default=(0.0, 0.0, 0.0), description="Position offset [m].")
    axes: Literal["world", "yaw"] = Field(default="yaw", description="Axes the offset is expressed in.")
    yaw: float | None = Field(default=None, description="Frame yaw relative to the reference yaw [rad].")
    quat: tuple[float, float, float, float] | None = Field(default=None, description="World orientation (wxyz).")
    axis: Vec3 | None = Field(default=None, description="Tool axis in the frame's coordinates.")
    direction: Vec3 | None = Field(default=None, description="World direction the axis points along.")

    @model_validator(mode="after")
    def _one_orientation(self) -> TargetSpec:
        given = [n for n in ("yaw", "quat", "axis") if getattr(self, n) is not None]
        if len(given) > 1:
            raise ValueError(f"give at most one of yaw, quat, axis+direction; got {', '.join(given)}")
        if (self.axis is None) != (self.direction is None):
            raise ValueError("axis and direction must be given together")
        if self.quat is not None and not math.isclose(math.hypot(*self.quat), 1.0, abs_tol=1e-3):
            raise ValueError(f"quat must be a unit quaternion (w, x, y, z), got {self.quat}")
        return self


class _Phase(_Strict):
    name: str | None = Field(default=None, description="Label in progress and results (default: kind + index).")
    timeout: float = Field(default=10.0, gt=0, description="Simulated time before the phase fails [s].")


class MovePhase(_Phase):
    """Move one or both tool frames to targets along straight lines."""

    kind: Literal["move"]
    targets: list[TargetSpec] = Field(min_length=1, max_length=2)
    tolerance: float = Field(default=0.005, gt=0, description="Position tolerance of the real frames [m].")
    speed: float = Field(default=0.15, gt=0, description="Cartesian speed of the moving setpoint [m/s].")


class PushPhase(_Phase):
    """Push an object to a target with one tool frame, re-planning from the object's live pose."""

    kind: Literal["push"]
    frame: str = Field(description="Tool frame that pushes, e.g. left_tool.")
    object: str = Field(description="Free body to push, e.g. cube.")
    target: str = Field(description="Body marking where the object should end, e.g. cube_target.")
    height: float = Field(default=0.0, description="Tool height relative to the object centre while pushing [m].")
    approach: float = Field(default=0.05, gt=0, description="Gap behind the object before a push [m].")
    clearance: float = Field(default=0.08, gt=0, description="Height above the object when moving around it [m].")
    tolerance: float = Field(default=0.002, gt=0, description="Planar object error that ends the phase [m].")
    attempts: int = Field(default=6, ge=1, description="Pushes before the phase gives up.")
    speed: float = Field(default=0.12, gt=0, description="Speed of approach moves [m/s].")
    push_speed: float = Field(default=0.05, gt=0, description="Speed while in contact [m/s].")
    yaw: float = Field(default=0.0, description="Tool yaw relative to the push direction [rad].")


class GraspPhase(_Phase):
    """Clamp an object between two pad frames by squeezing along the object's lateral (y) axis."""

    kind: Literal["grasp"]
    object: str
    frames: tuple[str, str] = Field(default=("left_pad", "right_pad"), description="Pads on the +y and -y side.")
    half_width: float = Field(gt=0, description="Half the object's width between the pads [m].")
    height: float = Field(default=0.0, description="Pad height relative to the object origin [m].")
    gap: float = Field(default=0.04, gt=0, description="Pad distance from the surface before closing [m].")
    squeeze: float = Field(default=0.01, ge=0, description="How far the pad targets go inside the surface [m].")
    hold: float = Field(default=0.3, ge=0, description="Time the squeeze is held before the phase ends [s].")
    speed: float = Field(default=0.1, gt=0, description="Approach speed [m/s].")


class Waypoint(_Strict):
    """Where the grasped object's origin should pass: a body-relative or world position and yaw."""

    relative_to: str = "world"
    offset: Vec3 = (0.0, 0.0, 0.0)
    axes: Literal["world", "yaw"] = "world"
    yaw: float | None = Field(default=None, description="Object yaw relative to the reference yaw [rad].")
    heading: Literal["reference", "radial"] = Field(
        default="reference",
        description="Yaw base: the reference body's yaw, or radial (facing away from the robot's chest axis).",
    )
    correct: bool = Field(default=False, description="Here, shift the rest of the path by the live planar error.")


class CarryPhase(_Phase):
    """Move a clamped object through waypoints while the pads keep their relative pose."""

    kind: Literal["carry"]
    object: str
    waypoints: list[Waypoint] = Field(min_length=1)
    tolerance: float = Field(default=0.003, gt=0, description="Planar object error accepted when correcting [m].")
    corrections: int = Field(default=3, ge=0, description="Closed-loop shifts allowed per correcting waypoint.")
    speed: float = Field(default=0.1, gt=0, description="Cartesian speed of the object setpoint [m/s].")
    relative_cost: float = Field(default=10.0, ge=0, description="Weight of the pads' relative pose task.")


class ReleasePhase(_Phase):
    """Open the pads away from the object, then retreat upwards."""

    kind: Literal["release"]
    object: str
    gap: float = Field(default=0.05, gt=0, description="How far the pads back away from the object [m].")
    lift: float = Field(default=0.08, ge=0, description="How far the pads then rise [m].")
    speed: float = Field(default=0.1, gt=0)


class JointsPhase(_Phase):
    """Drive named joints to positions (others hold)."""

    kind: Literal["joints"]
    positions: dict[str, float] = Field(min_length=1, description="Joint -> angle [rad].")
    tolerance: float = Field(default=0.01, gt=0, description="Joint tolerance [rad].")


class WaitPhase(_Phase):
    """Hold the current references for a while."""

    kind: Literal["wait"]
    duration: float = Field(gt=0, description="[s]")


Phase = Annotated[
    MovePhase | PushPhase | GraspPhase | CarryPhase | ReleasePhase | JointsPhase | WaitPhase,
    Field(discriminator="kind"),
]


class ManipulationConfig(_Strict):
    """A whole manipulation run."""

    task: str = Field(description="Name of the run in outputs.")
    scene: SceneConfig
    object: str = Field(description="Body whose final error is reported.")
    target: str = Field(description="Body marking the object's target.")
    start: Literal["home", "zero"] = Field(default="home", description="Start keyframe of the robot.")
    success_threshold: float = Field(default=0.02, gt=0, description="3-D object error counted as success [m].")
    gains: str = Field(default="default", description="Gains file (bundled name or path).")
    ik: IKConfig = Field(default_factory=IKConfig)
    trajectory: TrajectoryLimits = Field(default_factory=TrajectoryLimits)
    timing: TimingConfig = Field(default_factory=TimingConfig)
    seed: int = Field(default=0, ge=0, description="Seed of the run's own random draws (a sweep sets one per episode).")
    phases: list[Phase] = Field(min_length=1)

    def phase_name(self, index: int) -> str:
        """The phase's name, or ``kind[index]`` when it has none."""
        phase = self.phases[index]
        return phase.name or f"{phase.kind}[{index}]"


def apply_override(doc: dict[str, Any], assignment: str, source: str = "--set") -> None:
    """Apply one ``dotted.key=value`` override (value parsed as YAML; list items by index) in place.

    Raises:
        ConfigError: Malformed assignment or a path through something that is not a mapping or list.
    """
    key, sep, raw = assignment.partition("=")
    if not sep or not key:
        example = "scene.poses.cube.pos=[0.35,0,0.91]"
        raise ConfigError(f"{source} {assignment!r}: expected dotted.key=value, e.g. {example}")
    value = yaml.safe_load(raw)
    parts = key.split(".")
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


def _dotted(loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("move", "push", "grasp", "carry", "release", "joints", "wait") and out.endswith("]"):
            continue  # pydantic's discriminator tag adds nothing for the reader
        else:
            out += f".{part}" if out else str(part)
    return out


def format_validation_error(source: str, exc: ValidationError) -> str:
    """One line: ``file: dotted.key: message (got value)`` for the first error, plus a count of the rest."""
    errors = exc.errors()
    first = errors[0]
    key = _dotted(tuple(first["loc"])) or "<top level>"
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] == "extra_forbidden":
        parent = first["loc"][:-1]
        msg = f"unknown key; valid: {', '.join(_valid_keys(parent))}"
    elif first["type"] == "union_tag_invalid":
        msg = "unknown phase kind; valid: move, push, grasp, carry, release, joints, wait"
    got = first.get("input")
    shown = "" if first["type"] in ("missing", "extra_forbidden") or isinstance(got, dict) else f" (got {got!r})"
    more = f" [+{len(errors) - 1} more]" if len(errors) > 1 else ""
    return f"{source}: {key}: {msg}{shown}{more}"


_PHASE_MODELS: dict[str, type[BaseModel]] = {
    "move": MovePhase, "push": PushPhase, "grasp": GraspPhase, "carry": CarryPhase,
    "release": ReleasePhase, "joints": JointsPhase, "wait": WaitPhase,
}


def _valid_keys(loc: tuple[int | str, ...]) -> list[str]:
    """Keys accepted at a location of the config (for 'unknown key' messages)."""
    model: type[BaseModel] | None = ManipulationConfig
    skip_key = False
    for part in loc:
        if isinstance(part, int):
            continue
        if skip_key:  # a user key of a dict field (e.g. the body name in scene.poses)
            skip_key = False
            continue
        if part in _PHASE_MODELS:
            model = _PHASE_MODELS[part]
            continue
        field = model.model_fields.get(part) if model is not None else None
        if field is None:
            return []
        skip_key = getattr(field.annotation, "__origin__", None) is dict
        model = _model_in(field.annotation)
    return sorted(model.model_fields) if model is not None else []


def _model_in(annotation: Any) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def load_config(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> ManipulationConfig:
    """Read, override and validate a manipulation YAML.

    Raises:
        ConfigError: Missing file, invalid YAML, a bad override or a schema violation (one line each).
    """
    file = Path(path)
    if not file.is_file():
        bundled = sorted(p.name for p in (Path("configs")).glob("*.yaml")) if Path("configs").is_dir() else []
        hint = f"; configs here: {', '.join(bundled)}" if bundled else ""
        raise ConfigError(f"{file}: no such config file{hint}")
    doc = read_yaml_mapping(file, "a mapping at the top level")
    for assignment in overrides:
        apply_override(doc, assignment)
    try:
        return ManipulationConfig.model_validate(doc)
    except ValidationError as exc:
        raise ConfigError(format_validation_error(str(file), exc)) from None
