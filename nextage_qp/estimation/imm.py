r"""Object pose estimation: an interacting multiple model (IMM) filter on position and roll / pitch / yaw.

A camera reports an object's pose late (``latency``), at its own rate, with noise, and now and then not at all.
The filter keeps six decoupled axes (x, y, z [m]; roll, pitch, yaw [rad]), each a position-velocity pair, under
three motion models:

* *resting*: the position is constant up to a tiny random walk and the velocity is zero; it averages the noise
  of an object at rest down as a running mean would;
* *moving*: constant velocity under white-noise acceleration of spectral density :math:`q` (the
  ``accel_pos`` / ``accel_rot`` of the config), for an object pushed or carried;
* *manoeuvring*: the same with ``MANOEUVRE_GAIN`` times :math:`q`, for starts, stops and shoves.

.. math::

    F = \begin{bmatrix}1 & \Delta t\\ 0 & 1\end{bmatrix},\quad
    Q = q\begin{bmatrix}\Delta t^3/3 & \Delta t^2/2\\ \Delta t^2/2 & \Delta t\end{bmatrix},\quad
    H = \begin{bmatrix}1 & 0\end{bmatrix},\quad R = \sigma^2

Each axis keeps its own model probabilities (an object pushed along the table moves in x and y while its height
and tilt rest): every measurement re-weights the models of each axis by their likelihood (IMM mixing with a
``STAY`` probability of keeping the model), and the estimate is their probability-weighted mix.

The state lives at the time the last measurement *describes* (arrival less latency): a measurement is applied
at its own time stamp and :meth:`PoseKalman.estimate` predicts from there to now, which compensates the latency
and bridges dropouts (for at most ``COAST_S``, ``COAST_M`` and ``COAST_RAD``: an object unseen for longer, or
predicted to slide or turn farther than friction lets it, has stopped). A measurement whose
normalised innovation :math:`\sum_i \nu_i^2 / S_i` under the mixture
the models predict (weighted by their probabilities) exceeds the gate (the 99.9 % point of :math:`\chi^2_6`) is
rejected as an outlier; after ``reset_after`` rejections in a row the object has really moved, and the filter
restarts at the last of them, manoeuvring, with the velocity the last two show. A camera's partial view (the hand in
front of the object) is gated against the resting model alone and never makes up a speed: after a gap in the views a few
such fits would. ``PARTIAL_RUN`` rejected partial views in a row that agree with each other (a hand parked beside an
object it nudged) restart the filter at rest where they put it.
"""

from __future__ import annotations

import numpy as np

from nextage_qp.estimation.motion_models import ConstantVelocity, Resting, outer, wrap

CHI2_6_999 = 22.458
"""99.9 % point of the chi-square distribution with 6 degrees of freedom (the innovation gate)."""


STATIC_GAIN = 1e-5
"""Position random walk of the resting model [m^2/s per m^2/s^3 of ``accel_pos``] relative to the moving model's
process noise."""
MANOEUVRE_GAIN = 3e6
"""Process noise of the manoeuvring model relative to the moving one."""
STAY = 0.99
"""Probability that an axis keeps its model (resting, moving or manoeuvring) from one measurement to the next."""
COAST_S = 1.0
"""Longest time [s] past its last measurement that :meth:`PoseKalman.estimate` predicts motion: an object unseen for
longer has stopped where the prediction put it, rather than flying on at a speed a bad measurement gave it."""
COAST_M = 0.05
"""Longest distance [m] :meth:`PoseKalman.estimate` moves an object past its last measurement: more than a push moves it
in half a second and than friction lets a free object slide (v^2 / (2 mu g): 9 mm at 0.3 m/s with mu = 0.5); a longer
coast is a speed that wrong measurements gave the filter (the hand taken for the object as it passes over it)."""
COAST_RAD = 0.1
"""Longest angle [rad] (per rotation axis) :meth:`PoseKalman.estimate` turns an object past its last measurement. An
object turns while pushed, and then a contact carries its estimate, which does not turn; a free object unseen stops
turning within a fraction of a second. A longer turn is a rate that the last views before a gap gave the filter: a
camera's fit of a cube the hand was coming down beside jumped 7 deg in 0.08 s, and the coast turned the estimate 45
deg in the second the hand hid it, so that the push took the cube's face for its corner."""


PARTIAL_RUN = 15
"""Rejected partial views in a row (a second at 15 Hz) that, agreeing with each other within the gate, restart
the filter at rest at their mean: the object was moved while the hand hid it, and the hand stays in front of it."""


class PoseKalman:
    """Kalman estimate of one object's pose: resting, moving and manoeuvring models mixed per axis as an IMM.

    One constant-velocity filter cannot both average the noise of a resting object and follow a shove, so three
    models run side by side (see the module doc); each axis weighs them by how well they predicted its
    measurements, and the estimate is the probability-weighted mix.

    Args:
        noise_pos: Measurement noise per position axis [m] (standard deviation).
        noise_rot: Measurement noise per rotation axis [rad].
        accel_pos: Process noise of the moving model, white acceleration spectral density [m²/s³].
        accel_rot: The same for the rotation axes [rad²/s³].
        gate: Innovation gate (normalised squared innovation over all six axes, of the predicted mixture).
        reset_after: Rejected measurements in a row after which the filter restarts, manoeuvring.

    Attributes:
        accepted, rejected, resets: Measurement counts.
        mode: Probability of each model (resting, moving, manoeuvring) on each axis, (3, 6).
    """

    def __init__(self, noise_pos: float, noise_rot: float, *, accel_pos: float = 1e-4, accel_rot: float = 1e-3,
                 gate: float = CHI2_6_999, reset_after: int = 2) -> None:
        floor_pos, floor_rot = 1e-4, 1e-3  # a noiseless camera still gets a small R, so S never vanishes
        r = np.array([max(noise_pos, floor_pos) ** 2] * 3 + [max(noise_rot, floor_rot) ** 2] * 3)
        q = np.array([accel_pos] * 3 + [accel_rot] * 3)
        self.models = (Resting(q * STATIC_GAIN, r), ConstantVelocity(q, r), ConstantVelocity(q * MANOEUVRE_GAIN, r))
        n = len(self.models)
        self.trans = np.full((n, n), (1.0 - STAY) / (n - 1))
        np.fill_diagonal(self.trans, STAY)
        self.mode = np.full((n, 6), 1.0 / n)
        self.gate, self.reset_after = gate, reset_after
        self.t: float | None = None
        self.accepted = self.rejected = self.resets = 0
        self._misses: list[tuple[float, np.ndarray]] = []
        self._partials: list[np.ndarray] = []

    @property
    def initialised(self) -> bool:
        """True once a first measurement has been applied."""
        return self.t is not None

    def reset(self, t: float, z: np.ndarray) -> None:
        """Restart at measurement ``z`` (x, y, z, roll, pitch, yaw) taken at ``t`` [s], at rest, uncertain speed."""
        for m in self.models:
            m.x[:, 0], m.x[:, 1] = z, 0.0
            m.p[:] = 0.0
            m.p[:, 0, 0] = m.r
            m.p[:, 1, 1] = np.array([0.05**2] * 3 + [0.5**2] * 3)  # objects start (nearly) at rest
            m.pin()
        self.mode[:] = 1.0 / len(self.models)
        self.t, self._misses, self._partials = t, [], []

    def _restart_moving(self) -> None:
        """Restart at the last rejected measurement, manoeuvring, with the velocity of the last two."""
        t1, z1 = self._misses[-1]
        t0, z0 = self._misses[-2] if len(self._misses) > 1 else (t1, z1)
        self.reset(t1, z1)
        dt = t1 - t0
        if dt <= 0.0:
            return
        v = z1 - z0
        v[3:] = wrap(v[3:])
        for m in self.models:
            m.x[:, 1] = v / dt
            m.p[:, 1, 1] = 2.0 * m.r / dt**2
            m.p[:, 0, 1] = m.p[:, 1, 0] = m.r / dt
            m.pin()
        self.mode[:] = (1.0 - STAY) / (len(self.models) - 1)
        self.mode[-1] = STAY

    def start(self, t: float, z: np.ndarray, variance: np.ndarray) -> None:
        """Restart at ``z`` taken at ``t`` [s], at rest, with position/angle ``variance`` per axis (6,)."""
        self.reset(t, np.asarray(z, dtype=float))
        for m in self.models:
            m.p[:, 0, 0] = np.maximum(variance, 1e-12)
        self.mode[:] = (1.0 - STAY) / (len(self.models) - 1)  # at rest: a first jump is where it is, not a speed
        self.mode[0] = STAY

    def variance(self, t: float | None = None) -> np.ndarray:
        """Mode-weighted position/angle variance per axis (6,) at the last measurement, or predicted to ``t`` [s]."""
        dt = 0.0 if t is None or self.t is None else max(t - self.t, 0.0)
        return np.asarray(sum(w * m.predicted(dt)[1][:, 0, 0] for w, m in zip(self.mode, self.models, strict=True)))

    def update(self, t: float, z: np.ndarray, *, partial: bool = False, spread: float = 1.0) -> bool:
        """Apply a measurement ``z`` (x, y, z, roll, pitch, yaw) describing time ``t`` [s]; False if gated out.

        ``partial``: a partial view (the hand in front of the object), whose fit errs by more than the camera's noise
        and alike frame after frame. It may confirm where the filter holds the object, not move it: it is gated
        against the resting model alone (so noisy fits after a gap in the views cannot make up a speed), and a
        rejected one does not count towards a restart (nor breaks a run of rejected clear views that does); only
        ``PARTIAL_RUN`` rejected ones in a row that agree with each other restart the filter, at rest at their mean.
        ``spread``: this measurement's noise relative to the filter's (standard deviations; a fit to part of an object).
        It weighs the measurement, not its gate: which views are outliers, and which run of them restarts the filter,
        is decided under the filter's own noise, or covered views that a wider gate let through would break the runs
        that follow a moved object.
        """
        z = np.asarray(z, dtype=float)
        if self.t is None:
            self.reset(t, z)
            self.accepted += 1
            return True
        dt = max(t - self.t, 0.0)
        if self._nis(dt, z, resting=partial) > self.gate:
            self.rejected += 1
            if partial:
                self._partials = [*self._partials[1 - PARTIAL_RUN:], z]  # the last PARTIAL_RUN
                mean = self._agreed(np.array(self._partials)) if len(self._partials) == PARTIAL_RUN else None
                if mean is not None:
                    self.resets += 1
                    self.start(t, mean, self.models[0].r)
                return False
            self._misses.append((t, z))
            if len(self._misses) >= self.reset_after:  # not an outlier: the object really is elsewhere
                self.resets += 1
                self._restart_moving()
            return False
        prior = self._mix()
        r = self.models[0].r * spread**2
        logl = np.array([m.update(dt, z, r) for m in self.models])  # (models, axes)
        w = prior * np.exp(logl - logl.max(axis=0))
        self.mode = w / w.sum(axis=0)
        self.t, self._misses, self._partials = t, [], []
        self.accepted += 1
        return True

    def _agreed(self, zs: np.ndarray) -> np.ndarray | None:
        """The mean of the views ``zs`` (n, 6) when each is within the gate of it under the measurement noise."""
        d = zs - zs[-1]
        d[:, 3:] = wrap(d[:, 3:])
        mean = d.mean(axis=0)
        nu = d - mean
        return zs[-1] + mean if (np.sum(nu * nu / self.models[0].r, axis=1) <= self.gate).all() else None

    def _nis(self, dt: float, z: np.ndarray, resting: bool = False) -> float:
        """Normalised squared innovation of ``z`` under the predicted mixture (models by their prior), or at rest."""
        w = self.trans.T @ self.mode  # (models, axes)
        if resting:
            w = np.zeros_like(w)
            w[0] = 1.0
        preds = [m.predicted(dt) for m in self.models]
        mean = sum(wi * x[:, 0] for wi, (x, _) in zip(w, preds, strict=True))
        var = sum(wi * (p[:, 0, 0] + (x[:, 0] - mean) ** 2) for wi, (x, p) in zip(w, preds, strict=True))
        nu = z - mean
        nu[3:] = wrap(nu[3:])
        return float(np.sum(nu * nu / (var + self.models[0].r)))

    def _mix(self) -> np.ndarray:
        """IMM mixing, per axis: each model restarts from the mixture its predecessors hand it; returns the prior."""
        joint = self.trans[:, :, None] * self.mode[:, None, :]  # [i, j, axis]: from model i to model j
        prior = joint.sum(axis=0)
        weights = joint / prior[None]
        xs = [m.x for m in self.models]
        ps = [m.p for m in self.models]
        n = len(self.models)
        mixed = []
        for j in range(n):
            x0 = sum(weights[i, j][:, None] * xs[i] for i in range(n))
            p0 = sum(weights[i, j][:, None, None] * (ps[i] + outer(xs[i] - x0)) for i in range(n))
            mixed.append((x0, p0))
        for m, (x0, p0) in zip(self.models, mixed, strict=True):
            m.x, m.p = x0, p0
            m.pin()
        return prior

    def estimate(self, t: float) -> np.ndarray:
        """Pose (x, y, z, roll, pitch, yaw) predicted to ``t`` [s], within the coast limits of the last (module doc)."""
        if self.t is None:
            raise RuntimeError("no measurement yet")
        dt = min(max(t - self.t, 0.0), COAST_S)
        pose = np.asarray(sum(w * m.predicted(dt)[0][:, 0] for w, m in zip(self.mode, self.models, strict=True)))
        last = np.asarray(sum(w * m.x[:, 0] for w, m in zip(self.mode, self.models, strict=True)))
        shift = float(np.linalg.norm(pose[:3] - last[:3]))
        if shift > COAST_M:
            pose[:3] = last[:3] + (pose[:3] - last[:3]) * (COAST_M / shift)
        pose[3:] = last[3:] + np.clip(wrap(pose[3:] - last[3:]), -COAST_RAD, COAST_RAD)
        return pose
