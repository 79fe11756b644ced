"""Scaling an object's friction: every contact it can make becomes an explicit pair with scaled sliding friction.

Friction in MuJoCo: a contact between two geoms takes the larger of their coefficients (unless an explicit
``<pair>`` sets its own). Scaling one geom's coefficient therefore does not scale the contacts it takes part
in; :func:`scale_friction` turns every contact of a body into an explicit pair whose sliding coefficients are
the effective ones times the factor.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from nextage_qp.scene.compile import compile_spec


def _collides(m: mujoco.MjModel, g: int, h: int) -> bool:
    """Whether MuJoCo's broad phase would consider geoms ``g`` and ``h`` (contype/conaffinity, parent filter)."""
    if not ((m.geom_contype[g] & m.geom_conaffinity[h]) or (m.geom_contype[h] & m.geom_conaffinity[g])):
        return False
    wg, wh = int(m.body_weldid[m.geom_bodyid[g]]), int(m.body_weldid[m.geom_bodyid[h]])
    if wg == wh:
        return False
    if m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        return True
    pg, ph = int(m.body_weldid[m.body_parentid[wg]]), int(m.body_weldid[m.body_parentid[wh]])
    return not ((wg and ph == wg) or (wh and pg == wh))


def _mixed(m: mujoco.MjModel, g: int, h: int) -> dict[str, object]:
    """Contact parameters MuJoCo would mix for a dynamic contact of ``g`` and ``h`` (explicit pair fields)."""
    pg, ph = int(m.geom_priority[g]), int(m.geom_priority[h])
    if pg != ph:
        top = g if pg > ph else h
        fr = m.geom_friction[top]
        return {
            "condim": int(m.geom_condim[top]),
            "friction": [fr[0], fr[0], fr[1], fr[2], fr[2]],
            "solref": m.geom_solref[top].copy(),
            "solimp": m.geom_solimp[top].copy(),
            "margin": float(max(m.geom_margin[g], m.geom_margin[h])),
            "gap": float(max(m.geom_gap[g], m.geom_gap[h])),
        }
    fr = np.maximum(m.geom_friction[g], m.geom_friction[h])
    sg, sh = float(m.geom_solmix[g]), float(m.geom_solmix[h])
    mix = 0.5 if sg + sh < mujoco.mjMINVAL else sg / (sg + sh)
    return {
        "condim": int(max(m.geom_condim[g], m.geom_condim[h])),
        "friction": [fr[0], fr[0], fr[1], fr[2], fr[2]],
        "solref": mix * m.geom_solref[g] + (1 - mix) * m.geom_solref[h],
        "solimp": mix * m.geom_solimp[g] + (1 - mix) * m.geom_solimp[h],
        "margin": float(max(m.geom_margin[g], m.geom_margin[h])),
        "gap": float(max(m.geom_gap[g], m.geom_gap[h])),
    }


def scale_friction(spec: mujoco.MjSpec, factors: Mapping[str, float]) -> None:
    r"""Scale the sliding friction of every contact of the named bodies, in place.

    For body :math:`B` with factor :math:`s`, an explicit ``<pair>`` that involves :math:`B` gets its two
    sliding coefficients multiplied by :math:`s`; every other contact :math:`B` could make (by contype /
    conaffinity, not excluded, not parent-filtered) becomes an explicit pair with MuJoCo's mixed parameters and
    sliding friction :math:`s \cdot \max(\mu_B, \mu_{other})`, and the body pair is excluded from dynamic
    collision so that no contact is counted twice. Torsional and rolling friction are unchanged.
    """
    for k, geom in enumerate(spec.geoms):
        if not geom.name:
            geom.name = f"_geom{k}"
    model = compile_spec(spec, "scene (friction pairs)")
    geom_name = [model.geom(i).name for i in range(model.ngeom)]
    excluded = {
        frozenset((int(model.exclude_signature[i]) >> 16, int(model.exclude_signature[i]) & 0xFFFF))
        for i in range(model.nexclude)
    }
    paired: set[frozenset[int]] = set()
    for pair in spec.pairs:
        gids = frozenset((model.geom(pair.geomname1).id, model.geom(pair.geomname2).id))
        paired.add(gids)
        bodies = {model.body(int(model.geom_bodyid[g])).name for g in gids}
        factor = float(np.prod([factors[b] for b in bodies if b in factors]))
        if factor != 1.0:
            pair.friction = np.concatenate([np.asarray(pair.friction[:2]) * factor, pair.friction[2:]])
    for name, factor in factors.items():
        body = model.body(name).id
        own = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
        partners: set[int] = set()
        for g in own:
            for h in range(model.ngeom):
                hb = int(model.geom_bodyid[h])
                if frozenset((g, h)) in paired or frozenset((body, hb)) in excluded or not _collides(model, g, h):
                    continue
                params = _mixed(model, g, h)
                fr = np.asarray(params.pop("friction"), dtype=float)
                fr[:2] *= factor * factors.get(model.body(hb).name, 1.0)
                spec.add_pair(geomname1=geom_name[g], geomname2=geom_name[h], friction=fr, **params)
                paired.add(frozenset((g, h)))
                partners.add(hb)
        for hb in sorted(partners):
            spec.add_exclude(bodyname1=name, bodyname2=model.body(hb).name)
