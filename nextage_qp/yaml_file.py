"""Read a YAML file whose top level must be a mapping, turning every failure into a one-line ConfigError."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from nextage_qp.errors import ConfigError


def read_yaml_mapping(file: Path, expected: str) -> dict[str, Any]:
    """The mapping at the top of ``file``.

    Args:
        file: The YAML file.
        expected: What the top level should be, for the error message (e.g. "a mapping at the top level").

    Raises:
        ConfigError: The file cannot be read, is not valid YAML, or its top level is not a mapping.
    """
    try:
        doc = yaml.safe_load(file.read_text())
    except OSError as exc:
        raise ConfigError(f"{file}: cannot read: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{file}: not valid YAML: {' '.join(str(exc).split())}") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"{file}: expected {expected}")
    return doc
