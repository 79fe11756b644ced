"""URDF import: mesh paths resolved, COLLADA meshes converted, fixed-joint frames kept, then MuJoCo's URDF parser.

MuJoCo reads a URDF itself but resolves no ``package://`` path, reads no COLLADA (``.dae``) mesh and, by default,
fuses every link hung on a fixed joint into its parent (``tool0`` and the like vanish). :func:`urdf_spec` rewrites the
URDF first: each mesh file becomes an absolute path (``package://`` through :mod:`nextage_qp.robots.package_urls`,
relative
paths against the URDF's folder), each ``.dae`` (and ASCII STL) a binary STL converted with ``trimesh`` (the
``mesh`` extra) in a cache folder, and a ``<mujoco><compiler fusestatic="false" .../></mujoco>`` element keeps
fixed links as bodies.

The import welds the root link to the world and makes no actuator; a joint's ``<limit effort>`` becomes its
``actuatorfrcrange``, which the torque limits read.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, NamedTuple

import mujoco

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.robots.package_urls import PREFIX, missing_package_hint, resolve_package, split_package

MESH_SUFFIXES = (".stl", ".obj", ".msh")
"""Mesh files MuJoCo reads."""
KEEP_FRAMES = {"fusestatic": "false", "discardvisual": "false", "strippath": "false"}
"""Compiler settings the import adds: fixed links stay bodies, visual geoms stay, mesh paths stay absolute."""


class MeshIssue(NamedTuple):
    """A mesh the import cannot use: its reference as written, its link, what is wrong and what to do.

    ``kind``: ``package`` (a ``package://`` path not found), ``missing`` (no such file) or ``format`` (not a mesh
    MuJoCo reads, and not converted).
    """

    kind: str
    mesh: str
    link: str
    problem: str
    fix: str


def read_urdf(path: Path, source: str) -> ET.Element:
    """The root ``<robot>`` element of a URDF file.

    Raises:
        ConfigError: The file cannot be read or is not a URDF.
    """
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ConfigError(f"{source}: model {path}: not a readable URDF ({one_line(exc)})") from None
    if root.tag != "robot":
        raise ConfigError(f"{source}: model {path}: a URDF's top element is <robot>, got <{root.tag}>")
    return root


def _trimesh() -> Any:
    """The ``trimesh`` module, or None when it is not installed."""
    try:
        return importlib.import_module("trimesh")
    except ImportError:
        return None


def mesh_cache() -> Path:
    """Folder of converted meshes: ``$XDG_CACHE_HOME/nextage_qp/meshes`` (``~/.cache``), else a temporary folder."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "nextage_qp" / "meshes"
    try:
        base.mkdir(parents=True, exist_ok=True)
        if os.access(base, os.W_OK):
            return base
    except OSError:
        pass
    folder = Path(tempfile.gettempdir()) / "nextage_qp_meshes"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def unreadable_reason(path: Path) -> str | None:
    """Why MuJoCo cannot read a mesh file that ``trimesh`` can convert (COLLADA, ASCII STL), or None."""
    if path.suffix.lower() == ".dae":
        return "MuJoCo reads no COLLADA (.dae) mesh"
    if path.suffix.lower() == ".stl":
        try:
            with path.open("rb") as f:
                head = f.read(84)
            size = path.stat().st_size
        except OSError:
            return None
        if head.startswith(b"solid") and (len(head) < 84 or size != 84 + 50 * int.from_bytes(head[80:84], "little")):
            return "MuJoCo reads binary STL only and this one is ASCII"
    return None


def convert_mesh(path: Path) -> Path:
    """A COLLADA or ASCII STL mesh as a binary STL in :func:`mesh_cache` (named by its contents' hash; made once).

    Raises:
        ConfigError: ``trimesh`` is not installed or cannot read the file.
    """
    trimesh = _trimesh()
    if trimesh is None:
        raise ConfigError(f"{path}: reading COLLADA needs trimesh: pip install 'nextage-qp[mesh]'")
    data = path.read_bytes()
    out = mesh_cache() / f"{hashlib.sha256(data).hexdigest()[:24]}.stl"
    if out.is_file():
        return out
    try:
        mesh = trimesh.load(str(path), force="mesh")
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        mesh.export(str(tmp), file_type="stl")
        tmp.replace(out)
    except Exception as exc:  # trimesh raises many kinds; the message says which
        raise ConfigError(f"cannot convert it to STL: {one_line(exc)}") from None
    return out


def _link_of(root: ET.Element) -> dict[ET.Element, tuple[str, ET.Element]]:
    """Each ``<mesh>`` element -> (its link's name, the ``<visual>``/``<collision>`` element holding it)."""
    out = {}
    for link in root.iter("link"):
        for holder in [*link.findall("visual"), *link.findall("collision")]:
            for mesh in holder.iter("mesh"):
                out[mesh] = (link.get("name", "?"), holder)
    return out


def usable_mesh(ref: str, folder: Path, package_paths: tuple[Path, ...]) -> Path | tuple[str, str, str]:
    """The file MuJoCo can read for a URDF mesh reference, or why not: ``(kind, problem, fix)`` (see MeshIssue)."""
    if ref.startswith(PREFIX):
        try:
            found = resolve_package(ref, package_paths, folder)
        except ConfigError as exc:
            return "package", str(exc), "write package://NAME/PATH"
        if found is None:
            return "package", "package not found", missing_package_hint(split_package(ref)[0])
    else:
        found = (folder / ref.removeprefix("file://")).resolve()
        if not found.is_file():
            return "missing", f"file not found (looked for {found})", "fix the path (relative to the URDF's folder)"
    if found.suffix.lower() not in (*MESH_SUFFIXES, ".dae"):
        return ("format", f"MuJoCo cannot read {found.suffix} meshes",
                f"convert it to STL or OBJ (MuJoCo reads {', '.join(MESH_SUFFIXES)})")
    reason = unreadable_reason(found)
    if reason is None:
        return found
    if _trimesh() is None:
        return "format", f"{reason} and trimesh is not installed", ("pip install 'nextage-qp[mesh]' or convert it to "
                                                                    "binary STL or OBJ")
    try:
        return convert_mesh(found)
    except ConfigError as exc:
        return "format", str(exc), "convert it to binary STL or OBJ"


def resolve_meshes(root: ET.Element, folder: Path, package_paths: tuple[Path, ...], *,
                   drop: bool = False) -> list[MeshIssue]:
    """Rewrite every mesh filename of a URDF tree to a file MuJoCo reads; return the meshes that cannot be.

    ``package://`` paths are resolved with :func:`~nextage_qp.robots.package_urls.resolve_package`, relative paths
    against
    ``folder``; COLLADA and ASCII STL meshes are converted to binary STL (:func:`convert_mesh`). With ``drop``, the
    visual or collision element of an unusable mesh is removed (so the rest still compiles); without, it stays.
    """
    issues = []
    for mesh, (link, holder) in _link_of(root).items():
        ref = mesh.get("filename", "")
        found = usable_mesh(ref, folder, package_paths)
        if isinstance(found, Path):
            mesh.set("filename", str(found))
            continue
        issues.append(MeshIssue(found[0], ref, link, found[1], found[2]))
        if drop:
            next(el for el in root.iter("link") if holder in list(el)).remove(holder)
    return issues


def set_compiler(root: ET.Element, **attrs: str) -> None:
    """Set attributes of the URDF's ``<mujoco><compiler>`` element (made if missing; given values replaced)."""
    ext = root.find("mujoco")
    if ext is None:
        ext = ET.Element("mujoco")
        root.insert(0, ext)
    compiler = ext.find("compiler")
    if compiler is None:
        compiler = ET.SubElement(ext, "compiler")
    for key, value in attrs.items():
        compiler.set(key, value)


def spec_from_tree(root: ET.Element, path: Path, source: str) -> mujoco.MjSpec:
    """MuJoCo's spec of a (rewritten) URDF tree.

    Raises:
        ConfigError: MuJoCo refuses it: one line quoting MuJoCo.
    """
    try:
        return mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as exc:
        raise ConfigError(f"{source}: model {path}: MuJoCo cannot import it: {one_line(exc)}") from None


def urdf_spec(path: Path, package_paths: tuple[Path, ...], source: str) -> mujoco.MjSpec:
    """A URDF as a MuJoCo spec, its meshes resolved and its fixed-joint links kept as bodies (see the module doc).

    Raises:
        ConfigError: The URDF cannot be read, a mesh cannot be found or read (the message names it and the
            remedy), or MuJoCo refuses the model.
    """
    root = read_urdf(path, source)
    issues = resolve_meshes(root, path.parent, package_paths)
    if issues:
        bad = issues[0]
        more = f" (and {len(issues) - 1} more)" if len(issues) > 1 else ""
        raise ConfigError(f"{source}: model {path.name}: link {bad.link!r}: mesh {bad.mesh!r}: {bad.problem}; "
                          f"{bad.fix}{more}")
    set_compiler(root, **KEEP_FRAMES)
    return spec_from_tree(root, path, source)
