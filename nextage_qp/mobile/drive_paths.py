r"""Paths for a wheeled base, and their timing: what the ``drive`` phase hands the IK, tick by tick.

* :func:`around` — the shortest polyline from a start to a goal point that keeps out of circular obstacles
  (a visibility graph over points just outside each circle, searched with Dijkstra).
* :func:`polyline_motion` — a differential drive's motion along a polyline: turn in place towards each leg, drive
  it straight, turn to the final heading (it never needs to move sideways, and turns only where it has room).
* :func:`dubins` — a car's shortest forward path between two poses with a turning radius of at least
  :math:`R` (Dubins: two arcs joined by a line, or three arcs; six words, the shortest kept).
* :class:`Motion` — a path as timed poses: straight legs at ``speed`` and turns at ``turn_rate``, with
  :math:`\pm` ``accel`` ramps on every leg (trapezoids), sampled at any time.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from nextage_qp.mobile.drive_models import Pose2

Circle = tuple[float, float, float]
"""An obstacle's footprint: centre x, y and radius [m]."""
SAMPLES = 16
"""Points per obstacle circle in the visibility graph."""


def _clear(a: np.ndarray, b: np.ndarray, circles: Sequence[Circle]) -> bool:
    """Whether the segment a-b keeps out of every circle."""
    d = b - a
    length2 = float(d @ d)
    for cx, cy, r in circles:
        c = np.array([cx, cy])
        t = 0.0 if length2 == 0.0 else min(max(float((c - a) @ d) / length2, 0.0), 1.0)
        if float(np.linalg.norm(a + t * d - c)) < r - 1e-9:
            return False
    return True


def around(start: np.ndarray, goal: np.ndarray, circles: Sequence[Circle]) -> list[np.ndarray] | None:
    """The shortest polyline start -> goal (both included) outside every circle, or None when there is none.

    Raises nothing: a start or goal inside a circle has no path (None).
    """
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    nodes = [start, goal]
    for cx, cy, r in circles:
        ring = r / math.cos(math.pi / SAMPLES) + 1e-6  # the polygon's edges stay outside the circle
        nodes += [np.array([cx + ring * math.cos(a), cy + ring * math.sin(a)])
                  for a in np.linspace(0.0, 2 * math.pi, SAMPLES, endpoint=False)]
    inside = [any(math.dist(p, (cx, cy)) < r - 1e-9 for cx, cy, r in circles) for p in nodes]
    if inside[0] or inside[1]:
        return None
    best, prev = {0: 0.0}, {0: -1}
    queue: list[tuple[float, int]] = [(0.0, 0)]
    done: set[int] = set()
    while queue:
        cost, i = heapq.heappop(queue)
        if i in done:
            continue
        done.add(i)
        if i == 1:
            break
        for j, p in enumerate(nodes):
            if j in done or inside[j] or not _clear(nodes[i], p, circles):
                continue
            c = cost + float(np.linalg.norm(p - nodes[i]))
            if c < best.get(j, math.inf):
                best[j], prev[j] = c, i
                heapq.heappush(queue, (c, j))
    if 1 not in done:
        return None
    path, i = [], 1
    while i != -1:
        path.append(nodes[i])
        i = prev[i]
    return path[::-1]


class Leg(NamedTuple):
    """One piece of a motion: a straight leg (``turn`` 0), an arc, or a turn in place (``length`` 0).

    Attributes:
        length: Distance travelled [m] (signed: negative backwards).
        turn: Heading change [rad].
    """

    length: float
    turn: float


def _wrap(a: float) -> float:
    return math.remainder(a, 2.0 * math.pi)


def polyline_motion(start: Pose2, points: Sequence[np.ndarray], goal_yaw: float) -> list[Leg]:
    """A differential drive's legs through ``points`` (the first is where it starts): turn, drive, ..., turn."""
    legs, yaw = [], start.yaw
    for a, b in itertools.pairwise(points):
        d = np.asarray(b) - np.asarray(a)
        length = float(np.linalg.norm(d))
        if length < 1e-6:
            continue
        heading = math.atan2(float(d[1]), float(d[0]))
        legs += [Leg(0.0, _wrap(heading - yaw)), Leg(length, 0.0)]
        yaw = heading
    legs.append(Leg(0.0, _wrap(goal_yaw - yaw)))
    return [leg for leg in legs if abs(leg.length) > 1e-9 or abs(leg.turn) > 1e-9]


def dubins(start: Pose2, goal: Pose2, radius: float) -> list[Leg]:
    """The shortest forward path start -> goal with turns of radius ``radius`` [m] (Dubins' six words)."""
    dx, dy = goal.x - start.x, goal.y - start.y
    d = math.hypot(dx, dy) / radius
    theta = math.atan2(dy, dx)
    a, b = _mod(start.yaw - theta), _mod(goal.yaw - theta)
    best: tuple[float, list[tuple[str, float]]] | None = None
    for word, solve in _WORDS.items():
        found = solve(a, b, d)
        if found is None:
            continue
        total = sum(found)
        if best is None or total < best[0]:
            best = (total, list(zip(word, found, strict=True)))
    assert best is not None  # LSL or RSR always exists
    legs = []
    for kind, t in best[1]:
        if kind == "S":
            legs.append(Leg(t * radius, 0.0))
        else:
            legs.append(Leg(t * radius, t if kind == "L" else -t))
    return [leg for leg in legs if abs(leg.length) > 1e-9]


def _mod(x: float) -> float:
    return x % (2.0 * math.pi)


def _lsl(a: float, b: float, d: float) -> tuple[float, float, float] | None:
    p2 = 2 + d * d - 2 * math.cos(a - b) + 2 * d * (math.sin(a) - math.sin(b))
    if p2 < 0:
        return None
    tmp = math.atan2(math.cos(b) - math.cos(a), d + math.sin(a) - math.sin(b))
    return _mod(-a + tmp), math.sqrt(p2), _mod(b - tmp)


def _rsr(a: float, b: float, d: float) -> tuple[float, float, float] | None:
    p2 = 2 + d * d - 2 * math.cos(a - b) + 2 * d * (math.sin(b) - math.sin(a))
    if p2 < 0:
        return None
    tmp = math.atan2(math.cos(a) - math.cos(b), d - math.sin(a) + math.sin(b))
    return _mod(a - tmp), math.sqrt(p2), _mod(-b + tmp)


def _lsr(a: float, b: float, d: float) -> tuple[float, float, float] | None:
    p2 = -2 + d * d + 2 * math.cos(a - b) + 2 * d * (math.sin(a) + math.sin(b))
    if p2 < 0:
        return None
    p = math.sqrt(p2)
    tmp = math.atan2(-math.cos(a) - math.cos(b), d + math.sin(a) + math.sin(b)) - math.atan2(-2.0, p)
    return _mod(-a + tmp), p, _mod(-_mod(b) + tmp)


def _rsl(a: float, b: float, d: float) -> tuple[float, float, float] | None:
    p2 = -2 + d * d + 2 * math.cos(a - b) - 2 * d * (math.sin(a) + math.sin(b))
    if p2 < 0:
        return None
    p = math.sqrt(p2)
    tmp = math.atan2(math.cos(a) + math.cos(b), d - math.sin(a) - math.sin(b)) - math.atan2(2.0, p)
    return _mod(a - tmp), p, _mod(b - tmp)


def _rlr(a: float, b: float, d: float) -> tuple[float, float, float] | None:
    tmp = (6.0 - d * d + 2 * math.cos(a - b) + 2 * d * (math.sin(a) - math.sin(b))) / 8.0
    if abs(tmp) > 1.0:
        return None
    p = _mod(2 * math.pi - math.acos(tmp))
    t = _mod(a - math.atan2(math.cos(a) - math.cos(b), d - math.sin(a) + math.sin(b)) + p / 2.0)
    return t, p, _mod(a - b - t + p)


def _lrl(a: float, b: float, d: float) -> tuple[float, float, float] | None:
    tmp = (6.0 - d * d + 2 * math.cos(a - b) + 2 * d * (-math.sin(a) + math.sin(b))) / 8.0
    if abs(tmp) > 1.0:
        return None
    p = _mod(2 * math.pi - math.acos(tmp))
    t = _mod(-a - math.atan2(math.cos(a) - math.cos(b), d + math.sin(a) - math.sin(b)) + p / 2.0)
    return t, p, _mod(_mod(b) - a - t + p)


_WORDS = {"LSL": _lsl, "RSR": _rsr, "LSR": _lsr, "RSL": _rsl, "RLR": _rlr, "LRL": _lrl}


class Motion:
    """Legs timed: moving legs at ``speed`` [m/s], turns in place at ``turn_rate`` [rad/s], with ramps.

    Every leg has trapezoidal ramps of ``accel`` [m/s^2] (``accel / speed * turn_rate`` [rad/s^2] for turns).

    Args:
        start: Where the motion starts.
        legs: Its pieces, in order.
        speed, turn_rate, accel: The limits above.
    """

    def __init__(self, start: Pose2, legs: Sequence[Leg], speed: float, turn_rate: float, accel: float) -> None:
        self.start, self.legs = start, list(legs)
        self.speed, self.turn_rate, self.accel = speed, turn_rate, accel
        self._times, t = [], 0.0
        for leg in self.legs:
            self._times.append(t)
            t += self._duration(leg)
        self.duration = t

    def _profile(self, leg: Leg) -> tuple[float, float, float]:
        """(amount to cover, top rate, ramp rate) of a leg: metres for a leg that moves, radians for a turn."""
        if abs(leg.length) > 0.0:
            return abs(leg.length), self.speed, self.accel
        return abs(leg.turn), self.turn_rate, self.accel / self.speed * self.turn_rate

    def _duration(self, leg: Leg) -> float:
        amount, top, ramp = self._profile(leg)
        if amount <= top * top / ramp:  # a triangle: never reaches the top rate
            return 2.0 * math.sqrt(amount / ramp)
        return amount / top + top / ramp

    def _covered(self, leg: Leg, tau: float) -> float:
        """Fraction of the leg covered ``tau`` [s] into it."""
        amount, top, ramp = self._profile(leg)
        total = self._duration(leg)
        tau = min(max(tau, 0.0), total)
        peak = min(top, math.sqrt(amount * ramp))
        rise = peak / ramp
        if tau < rise:
            s = 0.5 * ramp * tau * tau
        elif tau > total - rise:
            s = amount - 0.5 * ramp * (total - tau) ** 2
        else:
            s = 0.5 * ramp * rise * rise + peak * (tau - rise)
        return s / amount if amount > 0 else 1.0

    def at(self, t: float) -> Pose2:
        """The pose ``t`` [s] after the start (the end pose after :attr:`duration`)."""
        pose = self.start
        for leg, t0 in zip(self.legs, self._times, strict=True):
            f = self._covered(leg, t - t0) if t < t0 + self._duration(leg) else 1.0
            if t < t0:
                break
            pose = _advance(pose, leg, f)
            if f < 1.0:
                break
        return pose

    @property
    def end(self) -> Pose2:
        """Where the motion ends."""
        return self.at(self.duration + 1.0)


def _advance(pose: Pose2, leg: Leg, fraction: float) -> Pose2:
    """The pose after ``fraction`` of a leg."""
    s, turn = leg.length * fraction, leg.turn * fraction
    if abs(turn) < 1e-12:
        return Pose2(pose.x + s * math.cos(pose.yaw), pose.y + s * math.sin(pose.yaw), pose.yaw)
    if abs(s) < 1e-12:
        return Pose2(pose.x, pose.y, pose.yaw + turn)
    radius = s / turn
    yaw = pose.yaw + turn
    return Pose2(pose.x + radius * (math.sin(yaw) - math.sin(pose.yaw)),
                 pose.y - radius * (math.cos(yaw) - math.cos(pose.yaw)), yaw)
