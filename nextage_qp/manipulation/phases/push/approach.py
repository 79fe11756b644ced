"""Where a push starts from: the reachable approach direction nearest the one wanted, and its planned route.

Directions are tried from the wanted one outwards through a fan of deviations, each way. For each, two transit
routes to the point ``approach`` behind the object's face: lift, then down beside the object (on the side the
tool is on) and in behind it; or over it and straight down behind it. The first route whose every waypoint the
planner reaches (each solved from the previous, see :class:`~nextage_qp.manipulation.route.PlannedRoute`) wins.

Where the scene has obstacles (clutter, a fixed object), an approach counts only when the arm also reaches along its
push line, as far as the object has to go along it, without the obstacles' collision rows holding it back
(:func:`line_clear`); when none does, the first reachable one is taken.

The fan is searched twice: first for a route whose waypoints the joints reach by descending from the previous
one (no random restarts: the arm moves continuously from where it is), then, only if none does, with the
planner's restarts (a route that may need the arm to reconfigure). A route found only by a restart is a far
joint move; a failing route costs a fraction of its restarts' descents in the first pass. A search that needs the
second pass repeats the first pass's descents from the current joints there (rare).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from nextage_qp.geometry import angle2, rotate2
from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.context import Geometry, View
from nextage_qp.manipulation.route import PlannedRoute

RAISE_STEP = 0.005
"""Step [m] by which a push whose approach is out of reach at its height is tried higher."""
LINE_STEP = 0.03
"""Spacing [m] of the points at which a push's line is checked (:func:`line_clear`)."""
FACE_MARGIN = 0.0
"""Least distance [m] from the tool point to the pushed object's top (0: the tool may rise to the top, the face below
it still meets the object)."""


class Approach(NamedTuple):
    """A planned approach.

    Attributes:
        direction: Planar unit push direction.
        lift: Point straight above the tool where the transit starts [m].
        yaw: Tool yaw for the push [rad].
        route: The planned transit.
        push_z: Tool height while pushing [m].
        tried: Directions tried to find it (each pass and height counting).
        raised: How far above ``spec.height`` it pushes [m].
    """

    direction: np.ndarray
    lift: np.ndarray
    yaw: float
    route: PlannedRoute
    push_z: float
    tried: int
    raised: float = 0.0


def routes(view: View, spec, tool: np.ndarray, d: np.ndarray, raise_by: float = 0.0) -> list[list[np.ndarray]]:
    """Transit routes (lift point first) from ``tool`` to behind ``spec.object`` for push direction ``d``.

    The tool goes to ``spec.height`` + ``raise_by`` over the object's centre.
    """
    obj = view.body_pose(spec.object).pos.copy()
    obj[2] = view.rest_height(spec.object)  # a pushed object stands on the table: its height is known, not seen
    d3, n3 = np.array([*d, 0.0]), np.array([-d[1], d[0], 0.0])
    behind = obj - d3 * (view.extent(spec.object, -d3) + spec.approach)  # off the face pushed (any shape)
    behind[2] = obj[2] + (spec.height or 0.0) + raise_by
    top = obj[2] + view.extent(spec.object, np.array([0.0, 0.0, 1.0]))
    lift = max(tool[2], top + spec.clearance)
    side = 1.0 if float((tool - obj) @ n3) >= 0 else -1.0
    beside = behind + side * n3 * (view.extent(spec.object, side * n3) + spec.approach)
    up = np.array([0.0, 0.0, lift - behind[2]])
    start = np.array([*tool[:2], lift])
    return [[start, beside + up, beside, behind], [start, behind + up, behind]]


def plan_approach(view: View, spec, tool: np.ndarray, wanted: np.ndarray, fan: Sequence[float],
                  target: Callable[[np.ndarray, float], FrameTarget], higher: bool | float = False,
                  extra: Sequence[tuple[FrameTarget, ...]] = (), blocked: list[str] | None = None) -> Approach | None:
    """The approach closest to the planar direction ``wanted`` within ``fan`` [rad] that the arm reaches, or None.

    ``spec`` is the push's spec (frame, object, approach, height, clearance, yaw); ``target(pos, yaw)`` the tool
    target at ``pos`` for a push at ``yaw``. With ``higher`` True, a push out of reach at its height is tried higher
    (:func:`raises`); a number: the push goes that much higher (as an earlier approach found it had to). ``extra``
    targets join the route's waypoints (the k-th of them the k-th waypoint, the last all later ones): another frame
    going home. ``blocked`` gathers why routes the arm reaches had no collision-free leg.
    """
    tried = 0
    heights = raises(view, spec) if higher is True else [float(higher)]  # a number: that raise only
    check_line = bool(view.obstacle_groups())  # obstacles beside the push: its line must keep the arm clear of them
    first: Approach | None = None  # the first reachable approach, whose line the arm may not keep clear along
    for raise_by in heights:
        for restarts in (False, True):  # continuous routes first (see the module doc)
            for deviation in (s * a for a in fan for s in ((1.0,) if a == 0 else (1.0, -1.0))):
                d = rotate2(wanted, deviation)
                yaw = float(np.arctan2(d[1], d[0])) + spec.yaw
                tried += 1
                for route in routes(view, spec, tool, d, raise_by):
                    planned = PlannedRoute([(target(p, yaw), *(extra[min(k, len(extra) - 1)] if extra else ()))
                                            for k, p in enumerate(route[1:])], plan=spec.plan, near=(spec.object,))
                    if planned.plan(view, restarts=restarts):
                        found = Approach(d, route[0], yaw, planned, float(route[-1][2]), tried, raise_by)
                        if not check_line or line_clear(view, spec, found, route[-1], target):
                            return found
                        first = first or found
                    if planned.blocked is not None and blocked is not None:
                        blocked.append(planned.blocked)
    return first._replace(tried=tried) if first is not None else None


def line_clear(view: View, spec, found: Approach, start: np.ndarray,
               target: Callable[[np.ndarray, float], FrameTarget]) -> bool:
    """Whether the arm reaches along ``found``'s push line keeping clear of the obstacles, as the IK drives it.

    The tool from ``start`` (behind the face) on along the push direction, as far as the object has to go along it,
    every ``LINE_STEP``: each point solved from the previous one (no restarts, the object itself not avoided). An arm
    the obstacles' collision rows hold off a point stalls there, and so would the push.
    """
    obj, tgt = view.body_pose(spec.object).pos, view.body_pose(spec.target).pos
    d = np.array([*found.direction, 0.0])
    travel = max(0.0, float((tgt - obj)[:2] @ found.direction)) + spec.approach
    q: np.ndarray | None = found.route.joints[-1]
    for k in range(1, int(np.ceil(travel / LINE_STEP)) + 1):
        point = start + d * min(k * LINE_STEP, travel)
        q = view.plan([target(point, found.yaw)], start=q, allow=frozenset({spec.object}), restarts=False)
        if q is None:
            return False
    return True


def raises(view: Geometry, spec) -> list[float]:
    """How far above ``spec.height`` the push may go [m], in the order tried.

    Not at all first, then in ``RAISE_STEP`` steps while the tool stays ``FACE_MARGIN`` below the object's top: a
    low object the tool cannot reach down to at the configured height is pushed as low as the arm can go.
    """
    top = view.extent(spec.object, np.array([0.0, 0.0, 1.0]))
    room = top - FACE_MARGIN - (spec.height or 0.0)
    return [0.0] + [k * RAISE_STEP for k in range(1, int(room / RAISE_STEP) + 1)]


def deviation(d: np.ndarray, wanted: np.ndarray) -> float:
    """Angle between two planar unit directions [rad]."""
    return abs(angle2(d, wanted))


def plan_handover(view: View, spec, frame: str, wanted: np.ndarray, fan: Sequence[float],
                  target: Callable[..., FrameTarget], higher: bool | float,
                  best: Approach | None) -> tuple[str, Approach] | None:
    """Another of the push's tools with an approach nearer ``wanted`` than ``best``, and that approach, or None.

    The tools are ``spec.frame`` and ``spec.other_frames``; ``best`` is the plan of the tool ``frame`` pushing now
    (None: it reaches none); ``target(pos, yaw, frame)`` is a tool's target. Each other tool tries only the deviations
    of ``fan`` smaller than the best found so far; its route lifts ``frame`` clear of the object, then takes it to where
    the default posture holds it.
    """
    limit = np.inf if best is None else deviation(best.direction, wanted)
    here = view.commanded_pose(frame).pos  # the tool leaving rises clear of the object first, then goes home
    top = view.rest_height(spec.object) + view.extent(spec.object, np.array([0.0, 0.0, 1.0]))
    up = np.array([*here[:2], max(here[2], top + spec.clearance)])
    home = ((FrameTarget(frame, pos=up),), (FrameTarget(frame, pos=view.pose_at(frame, view.default_posture()).pos),))
    found = None
    for other in (spec.frame, *spec.other_frames):
        nearer = [a for a in fan if a < limit - 1e-6]
        if other == frame or not nearer:
            continue
        plan = plan_approach(view, spec, view.commanded_pose(other).pos, wanted, nearer,
                             functools.partial(target, frame=other), higher=higher, extra=home)
        if plan is not None:
            found, limit = (other, plan), deviation(plan.direction, wanted)
    return found
