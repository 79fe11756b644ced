"""Compiling a scene's spec: MuJoCo's message on one line, and the warnings every composed scene raises dropped."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator

import mujoco

from nextage_qp.errors import ConfigError, one_line

_QUIET = ("empty prefix", "Attach conflict")
"""MuJoCo warns on every compile of a spec a robot was attached to with an empty prefix (the robot keeps its
names), and where the robot model's options differ from the scene's (the scene's are kept, by design: the Z1's
``impratio``); those warnings are dropped."""


@contextlib.contextmanager
def quiet_prefix_warning() -> Iterator[None]:
    """Drop MuJoCo's warnings of :data:`_QUIET` (C and Python) inside the block; forward the others."""
    previous = mujoco.get_mju_user_warning()

    def forward(message: str) -> None:
        if any(quiet in message for quiet in _QUIET):
            return
        if previous is not None:
            previous(message)
        else:  # MuJoCo's own default
            print(f"WARNING: {message}")

    mujoco.set_mju_user_warning(forward)
    try:
        with warnings.catch_warnings():
            for quiet in _QUIET:
                warnings.filterwarnings("ignore", message=f".*{quiet}")
            yield
    finally:
        mujoco.set_mju_user_warning(previous)


def compile_spec(spec: mujoco.MjSpec, source: str) -> mujoco.MjModel:
    """Compile a spec (raises :class:`ConfigError` with MuJoCo's message on one line)."""
    try:
        with quiet_prefix_warning():
            return spec.compile()
    except ValueError as exc:
        raise ConfigError(f"{source} does not compile: {one_line(exc)}") from None
