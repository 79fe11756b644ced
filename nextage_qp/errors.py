"""One exception hierarchy for everything nextage_qp raises on bad input or failure.

The CLI prints ``str(error)`` on one line (no traceback) and exits with code 2.
"""

from __future__ import annotations

from collections.abc import Iterable


class NextageQPError(Exception):
    """Base class of every error raised by nextage_qp.

    Args:
        message: The one-line message.
        source: The file the error is in (a config, robot or scene file), when known.
        key: The dotted key it is about (``scene.objects.box.size``), when known.
        phase: The phase of a run it happened in, when known.
    """

    def __init__(self, message: str = "", *, source: str | None = None, key: str | None = None,
                 phase: str | None = None) -> None:
        super().__init__(message)
        self.source, self.key, self.phase = source, key, phase


class ConfigError(NextageQPError):
    """A configuration file or value is invalid."""


class InfeasibleError(ConfigError):
    """The config is valid, but its scene asks for what cannot be done (e.g. a target overlapping an obstacle)."""


class UnknownNameError(NextageQPError, KeyError):
    """A name (joint, frame, object, geom group, ...) is not in the model.

    Args:
        kind: What kind of name was looked up, e.g. ``"frame"`` or ``"joint"``.
        name: The name that was not found.
        valid: The names that would have been accepted.
    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = tuple(valid)
        super().__init__(f"unknown {kind} {name!r}; valid: {', '.join(self.valid)}")

    def __str__(self) -> str:  # KeyError would quote the message otherwise
        return str(self.args[0])


class UnknownFrameError(UnknownNameError):
    """A frame (body or site) name is not in the model."""

    def __init__(self, name: str, valid: Iterable[str]) -> None:
        super().__init__("frame", name, valid)


class UnknownJointError(UnknownNameError):
    """A joint name is not one of the robot's joints."""

    def __init__(self, name: str, valid: Iterable[str]) -> None:
        super().__init__("joint", name, valid)


class IKError(NextageQPError):
    """The inverse kinematics problem could not be solved (e.g. an infeasible QP)."""


class TrajectoryError(NextageQPError):
    """Ruckig rejected its input or failed to compute a trajectory."""


class SimulationError(NextageQPError):
    """The simulation diverged (NaN or runaway state) or MuJoCo raised a warning."""


class SensorError(SimulationError):
    """A sensor failed: it returned NaN or froze."""


class PhaseError(NextageQPError):
    """A manipulation phase failed (timeout or unreachable target)."""


def one_line(text: object) -> str:
    """``text`` (an exception, a message) as one line: every run of whitespace, newlines included, one space."""
    return " ".join(str(text).split())
