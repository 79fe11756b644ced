"""What follows a push (:mod:`~nextage_qp.manipulation.phases.push`): the hold, the judgement and the retreat.

After the push stops, the object comes to rest against the tool and the push is judged: within ``tolerance`` the
tool retreats and the phase is done; short on the same line it pushes again (``nudges``); otherwise it retreats and
approaches again along the error, up to ``attempts`` approaches, and with nothing left to try an error within
``accept`` ends the phase, a larger one fails it. A push the camera could not see (the hand hid the object) is judged
after backing off, once the object is in sight again (the tool first moves towards the robot's side, ``ASIDE``, which
folds the arm out of the camera's line of sight; still hidden after ``LOOK_S``, it moves on as far again, up to
``LOOK_AGAIN`` times, and then judges on the estimate it has). With ``look_to_judge`` every push is judged so, never
with the hand beside the object (a push judged short is then approached again rather than nudged).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from nextage_qp.errors import PhaseError
from nextage_qp.geometry import unit2
from nextage_qp.manipulation.context import View
from nextage_qp.manipulation.phases.push_spec import ASIDE, HIDDEN_S, LOOK_AGAIN, LOOK_S, SEEN_S
from nextage_qp.servo import Command

if TYPE_CHECKING:
    from nextage_qp.manipulation.phases.push import Push


def hold(p: Push, view: View) -> Command:
    """Let the object come to rest against the tool, then judge the push (see the module doc)."""
    c = p.spec
    if view.t - p.hold_from < c.settle:
        return p._command(allow=True)
    hidden = view.unseen_s(c.object) > HIDDEN_S
    if hidden or (c.look_to_judge and not p.blind_stop):  # hidden (or told to look): back off and look, then judge
        return look(p, view)
    if p.blind_stop:  # stopped to look, and the camera sees it: push on, steering from what it sees
        p._begin_push(touched=True)
        return p._command(allow=True)
    obj, tgt, err = p._planar(view)
    p.info["object_error_xy_m"] = err
    e = (tgt - obj)[:2]
    if err <= c.tolerance:
        return start_retreat(p, final=True)
    short = float(e @ p.d) > 0 and abs(float(e @ np.array([-p.d[1], p.d[0]]))) <= c.tolerance
    if short and p.nudges < c.nudges:
        p.nudges += 1
        p.info["nudges"] += 1
        p._begin_push(touched=True)
        return p._command(allow=True)
    if p.approaches < c.attempts:
        p.next_d = unit2(e)
        return start_retreat(p, final=False)
    return finish(p, err)


def look(p: Push, view: View) -> Command:
    """Back off, move aside and judge the push once the object is in sight.

    For a push the camera could not see, and for a knock seen when no approach is left or none reaches the object's
    new place: the view that saw the knock may be one that the hand beside the object smeared.
    """
    p.looking = True
    return start_retreat(p, final=False, view=view)


def no_approach(p: Push, view: View) -> PhaseError:
    """The error of a push that finds no reachable approach at its start, with the object's height."""
    c = p.spec
    tall = sum(view.extent(c.object, np.array([0.0, 0.0, z])) for z in (1.0, -1.0)) * 1e3
    return PhaseError(f"phase {p.name!r} (push): no approach to {c.object} ({tall:.0f} mm tall) within "
                      f"{np.degrees(max(c.fan)):.0f} deg of its line to {c.target} is reachable by {p.frame}: out of "
                      "the arm's reach at the push height, lower than the hand reaches down "
                      "(tools/push_contact_height.py), or a tool point inside the hand, which then collides with the "
                      "object (docs/robots.md)")


def finish(p: Push, err: float, cause: str = "") -> Command:
    """Nothing left to try: accept the error within ``accept`` (retreat and end) or fail (saying why: ``cause``)."""
    c = p.spec
    if err <= c.accept:
        return start_retreat(p, final=True)
    raise PhaseError(f"phase {p.name!r} (push): {c.object} is still {err * 1e3:.1f} mm from {c.target} "
                     f"after {p.approaches} approaches (tolerance {c.tolerance * 1e3:g} mm, accepted "
                     f"{c.accept * 1e3:g} mm){cause or f': all {c.attempts} attempts used'}")


def start_retreat(p: Push, final: bool, view: View | None = None) -> Command:
    """Back the tool off along the push, then up; ``final``: the phase ends there.

    ``view`` given: the retreat is to look at the object, and the tool then moves on, level, towards the robot's
    side (:func:`_aside`).
    """
    c = p.spec
    back = p.sp.pos - np.array([*p.d, 0.0]) * c.approach
    p.route = [back, back + np.array([0.0, 0.0, c.clearance])]
    if view is not None:
        p.route.append(_aside(p.route[-1], p.frame, view))
    p.stage, p.leg, p.final, p.seen_from, p.asides = "retreat", 0, final, None, 0
    return p._command(allow=True)


def retreat(p: Push, view: View) -> Command:
    """Follow the retreat; then judge a push the camera could not see, end the phase, or approach again."""
    c = p.spec
    if p.leg < len(p.route) and p.sp.advance(p.route[p.leg], c.speed, view.dt):
        p.leg, p.back_at = p.leg + 1, view.t
    if p.leg < len(p.route):
        return p._command(allow=p.leg == 0)
    if p.looking:  # backed off from a push the camera could not see: judge it once the object is in sight
        waited = view.t - p.back_at
        if view.unseen_s(c.object) > HIDDEN_S:
            p.seen_from = None
            if waited < LOOK_S:
                return p._command(allow=False)
            if p.asides < LOOK_AGAIN:  # the arm still hides it: fold further towards the robot's side, look again
                p.asides += 1
                p.route.append(_aside(p.route[-1], p.frame, view))
                return p._command(allow=False)
        else:
            p.seen_from = view.t if p.seen_from is None else p.seen_from
            if view.t - p.seen_from < SEEN_S and waited < LOOK_S + SEEN_S:
                return p._command(allow=False)
        p.looking = False
        obj, tgt, err = p._planar(view)
        p.info["object_error_xy_m"] = err
        if err <= c.tolerance:
            p.final = True
        elif p.approaches >= c.attempts and not p.blind_stop:
            return finish(p, err)
        else:
            p.next_d = unit2((tgt - obj)[:2])
            if p.blind_stop:  # it stopped to look, not to be judged: the next approach is no new attempt
                p.approaches -= 1
                p.info["looks"] = p.info.get("looks", 0) + 1
        p.blind_stop = False
    if p.final:
        return p._command(allow=False, done=view.settled())
    p._approach(view, p.next_d, full=p.full)
    if p.plan_failed and not p.full:  # no reachable side within the correction fan: try the whole fan
        p.approaches -= 1
        p._approach(view, p.next_d, full=True)
    p.full = False
    if p.plan_failed:  # no reachable side to correct from
        p.info["unreachable_corrections"] = p.info.get("unreachable_corrections", 0) + 1
        _, _, err = p._planar(view)
        return finish(p, err, f": no side to push it from towards {p.spec.target} is within the robot's reach")
    if not _worth_it(p, view):  # an accepted error, and a correction that could not reach the tolerance: keep it
        p.info["declined_corrections"] = p.info.get("declined_corrections", 0) + 1
        p.stage, p.final, p.approaches = "retreat", True, p.approaches - 1
        p.info["attempts"] = p.approaches  # the declined one was planned, not made
        return p._command(allow=False, done=view.settled())
    return p._command(allow=False)


def _worth_it(p: Push, view: View) -> bool:
    """Whether the correction just planned may be pushed.

    It may when the error is beyond ``accept`` (nothing to lose), or when a push along the planned direction, even a
    perfect one, could bring it within ``tolerance``: a perfect push along the unit direction ``d`` removes the
    error's component along it and leaves the rest, ``err * sin`` of the angle between ``d`` and where the object
    should go (all of it when ``d`` points away). Where the reachable side deviates so far that this rest exceeds the
    tolerance, the push could only trade an accepted error for a gamble: a push across the object's face at an angle
    shoves it sideways too.
    """
    c = p.spec
    obj, tgt, err = p._planar(view)
    if err > c.accept or err <= c.tolerance:
        return True
    e = (tgt - obj)[:2] / err
    rest = err * abs(float(e[0] * p.d[1] - e[1] * p.d[0])) if float(e @ p.d) > 0 else err
    return rest <= c.tolerance


def _aside(point: np.ndarray, frame: str, view: View) -> np.ndarray:
    """``point`` moved level by ``ASIDE`` towards where the robot's default posture holds the tool ``frame``.

    The arm folds out of the camera's line of sight: backing off along the push leaves the hand over an object pushed
    away from the robot.
    """
    home = view.pose_at(frame, view.default_posture()).pos
    away = home[:2] - point[:2]
    dist = float(np.linalg.norm(away))
    step = away * min(ASIDE, dist) / dist if dist > 1e-9 else np.zeros(2)
    return np.array([*(point[:2] + step), point[2]])
