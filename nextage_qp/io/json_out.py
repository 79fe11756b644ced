"""Strict JSON out: numpy values as Python ones, NaN and infinities as null (``allow_nan=False`` parsers accept it)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def finite_json(x: Any) -> Any:
    """``x`` with numpy values turned into Python ones and every non-finite float into None (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): finite_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite_json(v) for v in x]
    if isinstance(x, (np.ndarray, np.generic)):
        return finite_json(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if x is None or isinstance(x, (str, int, float, bool)):
        return x
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def dumps(obj: Any, indent: int | None = 2) -> str:
    """``obj`` as strict JSON text (see :func:`finite_json`)."""
    return json.dumps(finite_json(obj), indent=indent, allow_nan=False)
