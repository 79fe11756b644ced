"""Output folders checked before anything runs: a file or folder that cannot be written is refused up front.

``os.access`` is not enough: it says yes to root everywhere, and to folders of ``/proc`` that take no new files.
A folder is writable when a temporary file can be made in it (and is gone again at once).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

from nextage_qp.errors import ConfigError


def nearest_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists (the writers make the missing folders below it)."""
    folder = path
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return folder


def name_limit(filename: Any) -> str:
    """The longest path component, for a message on a name too long where ``filename`` would be kept."""
    try:
        most = os.pathconf(nearest_existing(Path(os.fsdecode(filename)).absolute()), "PC_NAME_MAX")
    except (OSError, TypeError, ValueError):
        most = 255
    return f"at most {most} characters a path component"


def folder_problem(folder: Path) -> str | None:
    """Why files cannot be written into ``folder`` (made if missing), or None when they can."""
    existing = nearest_existing(folder)
    if not existing.is_dir():
        return f"{existing} is a file, not a folder"
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        return f"folder {existing} is not writable ({exc.strerror or exc})"
    return None


def refuse_overwriting(outputs: dict[str, Path | None], inputs: dict[str, Path | str | None]) -> None:
    """Refuse an output that would overwrite one of the command's inputs, or another of its outputs.

    Args:
        outputs: What each output is called (``--plot``) and the path it would be written to (None: not asked for).
        inputs: What each input is called (``the config``) and its path (None or missing files are skipped).

    Raises:
        ConfigError: Naming the output, the path and what is already there.
    """
    taken: dict[Path, str] = {}
    for name, path in inputs.items():
        if path is not None and Path(path).is_file():
            taken.setdefault(Path(path).resolve(), name)
    for name, path in outputs.items():
        if path is None:
            continue
        key = Path(path).resolve()
        if key in taken:
            raise ConfigError(f"{name} {path}: that is {taken[key]}, which this would overwrite; give {name} another "
                              "path")
        taken[key] = name if name.startswith("the ") else f"the {name} output"
