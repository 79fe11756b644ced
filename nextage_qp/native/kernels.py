"""Compiled loops of the collision rows (numba): one call per IK step each, not array operations and a Python loop.

:func:`near_pairs` and :func:`remember` are :class:`~nextage_qp.ik.broadphase.PairBounds`' distance bounds;
:func:`narrow_rows` is the narrow phase of :class:`~nextage_qp.ik.collision.ActiveCollisionLimit`, calling
MuJoCo's own ``mj_geomDistance`` and ``mj_jac`` (the shared library the ``mujoco`` package loaded) through their
addresses, so the rows are the ones the Python loop makes, to the bit. Each kernel is the loop its caller
documents, over arrays the caller owns (updated in place). Compiled once per machine (numba's cache).
"""

from __future__ import annotations

import ctypes
import glob
import os
from typing import Any

import mujoco
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


def _mujoco_library() -> ctypes.CDLL | None:
    """The MuJoCo shared library the ``mujoco`` package ships (already loaded by it), or None if not found."""
    folder = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(glob.glob(os.path.join(folder, pattern)))
        if found:
            try:
                return ctypes.CDLL(found[0])
            except OSError:
                return None
    return None


_LIB = _mujoco_library()


def address(name: str) -> int:
    """Address of one of MuJoCo's functions in its shared library (0: the library or the function not found)."""
    fn = getattr(_LIB, name, None) if _LIB is not None else None
    return 0 if fn is None else int(ctypes.cast(fn, ctypes.c_void_p).value or 0)


GEOM_DISTANCE = address("mj_geomDistance")
"""Address of ``mj_geomDistance`` (0: the library was not found; callers take their Python path)."""
JAC = address("mj_jac")
"""Address of ``mj_jac``."""
NATIVE = bool(GEOM_DISTANCE and JAC)
"""True when :func:`narrow_rows` can call MuJoCo."""


def _pointers(*args: types.Type) -> None:
    """Typing check of the intrinsics: addresses and ids are integers (a float would be a wrong address)."""
    if not all(isinstance(a, types.Integer) for a in args):
        raise TypeError(f"integer addresses and ids expected, got {args}")


def _geom_distance_typing(typingctx, fn, m, d, g1, g2, distmax, fromto):  # pragma: no cover - compiled
    """``mj_geomDistance(m, d, g1, g2, distmax, fromto)`` through its address ``fn``."""
    _pointers(fn, m, d, g1, g2, fromto)
    sig = types.float64(fn, m, d, g1, g2, types.float64, fromto)

    def codegen(context, builder, signature, args):
        fn, m, d, g1, g2, distmax, fromto = args
        i8p, f64p, i32 = ir.IntType(8).as_pointer(), ir.DoubleType().as_pointer(), ir.IntType(32)
        fnty = ir.FunctionType(ir.DoubleType(), [i8p, i8p, i32, i32, ir.DoubleType(), f64p])
        return builder.call(builder.inttoptr(fn, fnty.as_pointer()),
                            [builder.inttoptr(m, i8p), builder.inttoptr(d, i8p), builder.trunc(g1, i32),
                             builder.trunc(g2, i32), distmax, builder.inttoptr(fromto, f64p)])

    return sig, codegen


def _jac_typing(typingctx, fn, m, d, jacp, point, body):  # pragma: no cover - compiled
    """``mj_jac(m, d, jacp, NULL, point, body)`` through its address ``fn``."""
    _pointers(fn, m, d, jacp, point, body)
    sig = types.void(fn, m, d, jacp, point, body)

    def codegen(context, builder, signature, args):
        fn, m, d, jacp, point, body = args
        i8p, f64p, i32 = ir.IntType(8).as_pointer(), ir.DoubleType().as_pointer(), ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i8p, f64p, f64p, f64p, i32])
        builder.call(builder.inttoptr(fn, fnty.as_pointer()),
                     [builder.inttoptr(m, i8p), builder.inttoptr(d, i8p), builder.inttoptr(jacp, f64p),
                      ir.Constant(f64p, None), builder.inttoptr(point, f64p), builder.trunc(body, i32)])
        return context.get_dummy_value()

    return sig, codegen


_geom_distance: Any = intrinsic(_geom_distance_typing)
_jac: Any = intrinsic(_jac_typing)


@njit(cache=True)
def near_pairs(xpos, xmat, last_pos, last_mat, travel, chord, first, base, g1, g2, rsum, within,
               lever, step, gain, minimum, use_reach, out_idx, out_lower, out_reach):  # pragma: no cover - compiled
    """Travel update, then the pairs whose bound is below ``within`` (and that can bind within the box)."""
    moved_any = False
    for g in range(xpos.shape[0]):
        dx = xpos[g, 0] - last_pos[g, 0]
        dy = xpos[g, 1] - last_pos[g, 1]
        dz = xpos[g, 2] - last_pos[g, 2]
        s = 0.0
        for k in range(9):
            d = xmat[g, k] - last_mat[g, k]
            s += d * d
        m = np.sqrt(dx * dx + dy * dy + dz * dz) + chord[g] * np.sqrt(s)
        if first:
            m = 0.0
        if m != 0.0:
            moved_any = True
        travel[g] += m
        for k in range(3):
            last_pos[g, k] = xpos[g, k]
        for k in range(9):
            last_mat[g, k] = xmat[g, k]
    n = 0
    slack = 0
    nv = step.shape[0]
    for i in range(g1.shape[0]):
        a = g1[i]
        b = g2[i]
        lo = base[i] - travel[a] - travel[b]
        w = within[i]
        if not lo < w:
            continue
        dx = xpos[a, 0] - xpos[b, 0]
        dy = xpos[a, 1] - xpos[b, 1]
        dz = xpos[a, 2] - xpos[b, 2]
        sphere = np.sqrt(dx * dx + dy * dy + dz * dz) - rsum[i]
        if not sphere < w:
            continue
        if sphere > lo:
            lo = sphere
        if use_reach:
            r = 0.0
            for j in range(nv):
                r += lever[i, j] * step[j]  # inf lever x 0 step (a non-hinge dof): NaN, never prunes
            if gain * (lo - minimum[i]) > r:
                slack += 1
                continue
            out_reach[n] = r
        out_idx[n] = i
        out_lower[n] = lo
        n += 1
    return n, slack, moved_any


@njit(cache=True)
def remember(base, travel, g1, g2, pairs, values, exact, mark):  # pragma: no cover - compiled
    """Store ``values`` as the bounds of ``pairs`` at the current travel (``mark``: flag them exact)."""
    for k in range(pairs.shape[0]):
        i = pairs[k]
        base[i] = values[k] + travel[g1[i]] + travel[g2[i]]
        if mark:
            exact[i] = True


@njit(cache=True)
def narrow_rows(fn_distance, fn_jac, m, d, near, reach, use_reach, g1, g2, detect, minimum, exact, kept, body,
                gain, margin, jacs, zero1, dists, out_pair, out_dist, out_bound):  # pragma: no cover - compiled
    """The narrow phase and the witness points' Jacobians of the ``near`` pairs: returns (rows, slack)."""
    n = 0
    slack = 0
    f8 = np.uint64(8)  # bytes per double: addresses stay unsigned integers
    row, jac_size = np.uint64(kept.shape[1]), np.uint64(jacs.shape[2] * jacs.shape[3]) * f8
    kept_at, jacs_at = np.uint64(kept.ctypes.data), np.uint64(jacs.ctypes.data)
    for k in range(near.shape[0]):
        idx = near[k]
        a = g1[idx]
        b = g2[idx]
        dmax = detect[idx]
        start = kept_at + (np.uint64(idx) * row + np.uint64(1)) * f8  # the pair's witness points: from, then to
        end = start + np.uint64(3) * f8
        if exact[idx]:  # measured here already
            dist = kept[idx, 0]
        else:
            dist = _geom_distance(fn_distance, m, d, a, b, dmax + margin, start)
            kept[idx, 0] = dist
        dists[k] = dist
        if dist >= dmax:
            continue
        gap = dist - minimum[idx]
        bound = gain * gap if gap > 0.0 else 0.0
        if use_reach and bound > reach[k]:
            slack += 1
            continue
        if body[b] >= 0:  # geom2's Jacobian at its witness point ("to"), then geom1's ("from")
            _jac(fn_jac, m, d, jacs_at + np.uint64(2 * n) * jac_size, end, body[b])
        else:
            jacs[n, 0] = 0.0
        if body[a] >= 0:
            _jac(fn_jac, m, d, jacs_at + np.uint64(2 * n + 1) * jac_size, start, body[a])
            zero1[n] = False
        elif not zero1[n]:  # a side no joint moves: zeros (the slot keeps them until a moving side writes it)
            jacs[n, 1] = 0.0
            zero1[n] = True
        out_pair[n] = idx
        out_dist[n] = dist
        out_bound[n] = bound
        n += 1
    return n, slack


_warm: set[tuple[int, bool]] = set()


def warm_up(nv: int, box: bool) -> None:
    """Load (or compile) the kernels for an IK of ``nv`` dofs now, so no IK step pays for it.

    Called with the argument types the IK step passes (``box``: the step bound is the joint box's read-only array).
    """
    if (nv, box) in _warm:
        return
    f0, f1, i0, b0 = np.zeros(0), np.zeros(1), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool)
    step = np.zeros(nv)
    step.setflags(write=not box)
    near_pairs(np.zeros((1, 3)), np.zeros((1, 9)), np.zeros((1, 3)), np.zeros((1, 9)), f1.copy(), f1, True, f0, i0,
               i0, f0, f0, np.zeros((0, nv)), step, 0.5, f0, box, i0.copy(), f0.copy(), f0.copy())
    remember(f0, f1, i0, i0, i0, f0, b0, True)
    if NATIVE:
        narrow_rows(GEOM_DISTANCE, JAC, 0, 0, i0, f0, box, i0, i0, f0, f0, b0, np.zeros((0, 7)), i0, 0.5, 0.05,
                    np.zeros((0, 2, 3, nv)), b0, f0, i0, f0, f0)
        clearance(GEOM_DISTANCE, 0, 0, np.zeros((1, 3)), i0, i0, f0, 1.0, 0.04, np.zeros(6))  # OutcomeMonitor's
    _warm.add((nv, box))


@njit(cache=True)
def clearance(fn_distance, m, d, xpos, pair1, pair2, rsum, best, watch, fromto):  # pragma: no cover - compiled
    """Smallest distance of the pairs below ``max(best, watch)``, nearest bounding spheres first: (best, nearest).

    ``best``: the smallest found so far (it only shrinks), ``nearest``: this call's smallest, capped at ``watch``.
    A pair whose spheres' gap exceeds the current cut cannot lower either.
    """
    gap = np.empty(pair1.shape[0])
    for k in range(pair1.shape[0]):
        a = pair1[k]
        b = pair2[k]
        dx = xpos[a, 0] - xpos[b, 0]
        dy = xpos[a, 1] - xpos[b, 1]
        dz = xpos[a, 2] - xpos[b, 2]
        gap[k] = np.sqrt(dx * dx + dy * dy + dz * dz) - rsum[k]
    cut = max(best, watch)
    nearest = watch
    at = np.uint64(fromto.ctypes.data)
    for k in np.argsort(gap):
        if gap[k] > cut:
            break
        dist = _geom_distance(fn_distance, m, d, pair1[k], pair2[k], cut, at)
        best = min(best, dist)
        nearest = min(nearest, dist)
        cut = max(best, watch)
    return best, nearest


def clearance_python(model: mujoco.MjModel, data: mujoco.MjData, pair1: np.ndarray, pair2: np.ndarray,
                     rsum: np.ndarray, best: float, watch: float, fromto: np.ndarray) -> tuple[float, float]:
    """:func:`clearance` in Python (where MuJoCo's shared library was not found)."""
    pos = data.geom_xpos
    delta = pos.take(pair1, axis=0) - pos.take(pair2, axis=0)
    gap = np.sqrt(np.vecdot(delta, delta)) - rsum
    cut = max(best, watch)
    nearest = watch
    close = np.flatnonzero(gap <= cut)
    first, second, gaps = pair1.tolist(), pair2.tolist(), gap.tolist()
    for k in close[np.argsort(gap.take(close))].tolist():
        if gaps[k] > cut:
            break
        dist = mujoco.mj_geomDistance(model, data, first[k], second[k], cut, fromto)
        best, nearest = min(best, dist), min(nearest, dist)
        cut = max(best, watch)
    return best, nearest


@njit(cache=True)
def worst_contact(geom, dist, bodyid, mine, held, allowed, near, table, chain, clearance, table_clearance,
                  chain_slop, self_slop, resting):  # pragma: no cover - compiled
    """The counted contact with the least slack (distance less the distance it needs): (slack, index, needed).

    The planner's validity rule (:meth:`~nextage_qp.planning.world.CollisionWorld.room`) over MuJoCo's contacts
    ``geom`` (pairs of geom ids) at signed distances ``dist``: a contact counts when exactly one side is the robot's
    or a held object's (``mine``), or both are robot links (self-collision, half the slack: both may move), neither
    side is ``allowed`` nor the world body. Index -1: no contact counts.
    """
    best, at, need = np.inf, -1, 0.0
    for k in range(dist.shape[0]):
        b0 = bodyid[geom[k, 0]]
        b1 = bodyid[geom[k, 1]]
        if b0 == 0 or b1 == 0 or allowed[b0] or allowed[b1]:
            continue
        m0, m1 = mine[b0], mine[b1]
        if m0 and m1:
            if held[b0] or held[b1]:
                continue
            needed = -chain_slop if chain[b0, b1] else -self_slop
            slack = 0.5 * (dist[k] - needed)
        elif m0 or m1:
            other = b1 if m0 else b0
            if table[other]:
                needed = -resting if (held[b0] or held[b1]) else table_clearance
            elif near[other]:
                needed = 0.0
            else:
                needed = clearance
            slack = dist[k] - needed
        else:
            continue
        if slack < best:
            best, at, need = slack, k, needed
    return best, at, need
