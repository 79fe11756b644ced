"""``package://NAME/PATH`` references, as URDFs and robot files write them, resolved to files.

``NAME`` is looked up, in order: as a folder ``NAME`` in each search path (a robot file's ``package_paths``), as
a folder ``NAME`` beside the referring file or any folder above it (a ROS workspace's layout), and as an installed
Python distribution's package (located with :func:`importlib.util.find_spec`, never imported: the
``robosuite_models`` package carries MJCF robots).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path

from nextage_qp.errors import ConfigError

PREFIX = "package://"


def split_package(ref: str) -> tuple[str, str]:
    """``package://NAME/PATH`` -> ``(NAME, PATH)``.

    Raises:
        ConfigError: ``ref`` has no package name or no path.
    """
    name, _, rest = ref.removeprefix(PREFIX).partition("/")
    if not name or not rest:
        raise ConfigError(f"{ref!r}: a package reference reads package://NAME/PATH")
    return name, rest


def package_roots(name: str, search: Sequence[Path] = (), near: Path | None = None) -> list[Path]:
    """Folders that could hold package ``name``, most specific first (they need not hold the file)."""
    roots = [p / name for p in search] + [p for p in search if p.name == name]
    if near is not None:
        roots += [folder / name for folder in (near, *near.parents)] + [f for f in (near, *near.parents)
                                                                         if f.name == name]
    try:
        spec = importlib.util.find_spec(name) if name.isidentifier() else None
    except (ImportError, ValueError):
        spec = None
    if spec is not None and spec.submodule_search_locations:
        roots += [Path(p) for p in spec.submodule_search_locations]
    return roots


def resolve_package(ref: str, search: Sequence[Path] = (), near: Path | None = None) -> Path | None:
    """The file ``package://NAME/PATH`` names, or None when no root holds it."""
    name, rest = split_package(ref)
    for root in package_roots(name, search, near):
        if (root / rest).is_file():
            return (root / rest).resolve()
    return None


def missing_package_hint(name: str) -> str:
    """What to do when package ``name`` is not found: install it or add its parent folder to ``package_paths``."""
    return (f"install the Python package {name!r} (the bundled robots' models: pip install 'nextage-qp[robots]') "
            f"or add the folder holding {name}/ to package_paths")
