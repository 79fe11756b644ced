"""A robot as the framework sees it: a validated robot file, its paths resolved (:func:`load_robot`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nextage_qp.errors import ConfigError
from nextage_qp.io.yaml_file import read_yaml_mapping, validate
from nextage_qp.mobile.base_file import BaseFile
from nextage_qp.robots.cameras import CameraFile
from nextage_qp.robots.package_urls import PREFIX, missing_package_hint, resolve_package, split_package
from nextage_qp.robots.robot_file import (
    FrameFile,
    GainRule,
    GroupFile,
    MountFile,
    PushFaceFile,
    RobotFile,
    WorkspaceFile,
)

DEFAULT_ROBOT = "nextage"
"""The robot a config or command uses when it names none."""


@dataclass(frozen=True)
class Arm:
    """One arm: name, joints (shoulder to wrist) and the frames the phases use on it."""

    name: str
    joints: tuple[str, ...]
    wrist: str
    tool: str
    pad: str
    clamps: bool = True
    """Whether the robot file declares the pad (else ``pad`` is the wrist, which no clamp can use)."""

    @property
    def group(self) -> str:
        """Name of the arm's joint group and collision group: ``NAME_arm``."""
        return f"{self.name}_arm"


@dataclass(frozen=True)
class RobotDescription:
    """Everything a robot file says, with paths made absolute.

    Attributes:
        name: Robot name.
        source: The robot file (for messages).
        model: The MJCF or URDF file.
        arms: The arms, the first one on the +y side.
    """

    name: str
    source: str
    model: Path
    angle: str | None
    package_paths: tuple[Path, ...]
    mount: MountFile
    arms: tuple[Arm, ...]
    joint_groups: Mapping[str, tuple[str, ...]]
    frames: Mapping[str, FrameFile]
    collision_groups: Mapping[str, GroupFile]
    exclude: tuple[tuple[str, str], ...]
    keyframes: Mapping[str, str | Mapping[str, float]]
    gains: Path | GainRule
    gains_dir: Path | None
    torque_limits: float | Mapping[str, float] | None
    velocity_limits: float | Mapping[str, float] | None
    cameras: Mapping[str, CameraFile] = field(default_factory=dict)
    wrench_sensors: tuple[str, ...] = ()
    base: BaseFile | None = None
    workspace: WorkspaceFile | None = None
    push_face: PushFaceFile = field(default_factory=PushFaceFile)

    @property
    def joints(self) -> tuple[str, ...]:
        """Every joint the file names (arms first, then the groups); the robot orders them as the model does."""
        return tuple(j for arm in self.arms for j in arm.joints) + tuple(
            j for joints in self.joint_groups.values() for j in joints
        )

    @property
    def groups(self) -> dict[str, tuple[str, ...]]:
        """Joint groups: each arm's (``NAME_arm``) and the file's own."""
        return {**{arm.group: arm.joints for arm in self.arms}, **self.joint_groups}

    def where(self, joint: str) -> str:
        """The dotted key that lists ``joint`` (``arms[0].joints``, ``joint_groups.torso``), for messages."""
        for i, arm in enumerate(self.arms):
            if joint in arm.joints:
                return f"arms[{i}].joints"
        return next((f"joint_groups.{g}" for g, js in self.joint_groups.items() if joint in js), "joints")

    def arm(self, name: str) -> Arm:
        """The arm of that name (raises :class:`ConfigError` listing the arms)."""
        for arm in self.arms:
            if arm.name == name:
                return arm
        raise ConfigError(f"{self.source}: no arm {name!r}; arms: {', '.join(a.name for a in self.arms)}")


def robots_dir() -> Path:
    """The folder of the bundled robot files (``robots/`` in a checkout, ``robots_data/`` when installed)."""
    from nextage_qp.scene.files import package_root

    root = package_root()
    for name in ("robots_data", "robots"):
        if any((root / name).glob("*.yaml")):
            return root / name
    raise ConfigError(f"cannot find the bundled robot files (robots/*.yaml) under {root}")


def bundled_robots() -> list[str]:
    """Names of the bundled robot files."""
    return sorted(p.stem for p in robots_dir().glob("*.yaml"))


def robot_file(ref: str | Path | None) -> Path:
    """The robot file a config or command names: a bundled name (``nextage``) or a path to a YAML file.

    Raises:
        ConfigError: Neither; the message lists the bundled robots.
    """
    ref = DEFAULT_ROBOT if ref is None else ref
    path = Path(ref)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return path
    bundled = robots_dir() / (path.name if path.suffix in (".yaml", ".yml") else f"{path.name}.yaml")
    if path.parent == Path(".") and path.suffix in ("", ".yaml", ".yml") and bundled.is_file():
        return bundled  # a bundled robot's name, or its file name when no such file is here
    hint = (
        "a robot file (.yaml)"
        if path.suffix not in (".xml", ".urdf")
        else ("a robot file (.yaml; `nextage-qp robot init MODEL` writes one for a model)")
    )
    raise ConfigError(
        f"robot {str(ref)!r} not found; bundled robots: {', '.join(bundled_robots())} (or a path to {hint})"
    )


_PATH_KEYS = ("model", "gains", "gains_dir")
"""Keys of a robot file that hold a path relative to the file (and ``package_paths``, a list of them)."""


def _read_extended(path: Path, seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A robot file's mapping, on top of the file it ``extends``.

    Its keys win, its mappings add entries to the other's; the other's relative paths are made absolute.

    Raises:
        ConfigError: The file, or the one it extends, cannot be read, or the files extend each other in a circle.
    """
    doc = read_yaml_mapping(path, "a robot file (a mapping with name, model, arms)")
    if "phases" in doc or "randomize" in doc:
        what = "task config (it has phases)" if "phases" in doc else "sweep file (it has randomize)"
        raise ConfigError(f"{path}: this is a {what}, not a robot file: give a robot file (name, model, arms; "
                          "e.g. robots/nextage.yaml) or a bundled robot's name")
    parent = doc.pop("extends", None)
    if parent is None:
        return doc
    if not isinstance(parent, str) or not parent:
        raise ConfigError(f"{path}: extends: {parent!r} must be a robot file's path (relative to this file)")
    other = (path.resolve().parent / parent).resolve()
    if other in (*seen, path.resolve()):
        raise ConfigError(f"{path}: extends: {parent!r} extends this file again (a circle)")
    if not other.is_file():
        raise ConfigError(f"{path}: extends: {parent!r} not found (looked for {other})")
    base = _read_extended(other, (*seen, path.resolve()))
    for key in _PATH_KEYS:
        value = base.get(key)
        if isinstance(value, str) and not value.startswith(PREFIX) and not Path(value).is_absolute():
            base[key] = str((other.parent / value).resolve())
    if isinstance(base.get("package_paths"), list):
        base["package_paths"] = [str((other.parent / p).resolve()) for p in base["package_paths"]]
    merged = {**base, **doc}
    for key, value in doc.items():  # a mapping (collision_groups, frames, cameras, ...) adds to the other's
        if isinstance(value, dict) and isinstance(base.get(key), dict) and key != "base":
            merged[key] = {**base[key], **value}
    return merged


def load_robot(ref: str | Path | None = None) -> RobotDescription:
    """Load and validate a robot file (see :mod:`nextage_qp.robots.robot_file`).

    Raises:
        ConfigError: The file is missing or malformed: one line naming the file, the dotted key and what is valid.
    """
    path = robot_file(ref)
    shown = str(path)
    doc: RobotFile = validate(RobotFile, _read_extended(path), shown)
    here = path.resolve().parent
    search = tuple((here / p).resolve() for p in doc.package_paths)
    if doc.model.startswith(PREFIX):
        found = resolve_package(doc.model, search, here)
        if found is None:
            name = split_package(doc.model)[0]
            raise ConfigError(f"{shown}: model: {doc.model!r} not found: {missing_package_hint(name)}")
        model = found
    else:
        model = (here / doc.model).resolve()
    if model.is_dir():
        inside = sorted(p.name for p in model.iterdir() if p.suffix.lower() in (".xml", ".urdf"))[:5]
        raise ConfigError(f"{shown}: model: {doc.model!r} is a folder; name the model file in it"
                          f"{' (' + ', '.join(inside) + ')' if inside else ' (it has no .xml or .urdf file)'}")
    if not model.is_file():
        raise ConfigError(f"{shown}: model: {doc.model!r} not found (looked for {model})")
    if model.suffix.lower() not in (".xml", ".urdf"):
        raise ConfigError(f"{shown}: model: {doc.model!r} must be an MJCF (.xml) or URDF (.urdf) file")
    arms = tuple(Arm(a.name, a.joints, a.wrist, a.tool or a.wrist, a.pad or a.wrist, a.pad is not None)
                 for a in doc.arms)
    gains = doc.gains if isinstance(doc.gains, GainRule) else (here / doc.gains).resolve()
    if isinstance(gains, Path) and not gains.is_file():
        raise ConfigError(f"{shown}: gains: {doc.gains!r} not found (looked for {gains})")
    return RobotDescription(
        name=doc.name,
        source=shown,
        model=model,
        angle=doc.angle,
        package_paths=search,
        mount=doc.mount,
        arms=arms,
        joint_groups=dict(doc.joint_groups),
        frames=dict(doc.frames),
        collision_groups=dict(doc.collision_groups),
        exclude=doc.exclude,
        keyframes=dict(doc.keyframes),
        gains=gains,
        gains_dir=(here / doc.gains_dir).resolve() if doc.gains_dir else None,
        torque_limits=doc.torque_limits,
        velocity_limits=doc.velocity_limits,
        cameras=dict(doc.cameras),
        wrench_sensors=doc.wrench_sensors,
        base=doc.base,
        workspace=doc.workspace,
        push_face=doc.push_face,
    )
