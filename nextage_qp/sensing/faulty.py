"""Faulty sensors and external shoves: the :class:`~nextage_qp.sensing.sensors.Sensors` seam under a ``faults:`` block.

:class:`FaultySensors` turns the true state into what the controller gets: object poses from a simulated camera
(rate, latency, noise, dropouts) through a :class:`~nextage_qp.estimation.imm.PoseKalman` per object (or the latest
raw measurement), noisy joint states, noisy or failing force/torque sensors. It keeps the numbers the run
reports: estimate and raw errors against the truth, dropouts, gated measurements; with a camera
(:attr:`FaultySensors.measurer`) the measurements come from its images. :mod:`nextage_qp.sensing.setup` builds
them for a config.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.estimation.held import HeldEstimate
from nextage_qp.estimation.imm import PoseKalman
from nextage_qp.estimation.report import EstimateErrors
from nextage_qp.geometry import Pose, axis_angle, rpy_of, vector_pose, wrap, yaw_of
from nextage_qp.sensing.faults import EstimationConfig, FaultsConfig
from nextage_qp.sensing.sensors import Wrench


class _Track:
    """One object's camera stream, its filter and its error statistics."""

    def __init__(self, kalman: PoseKalman | None) -> None:
        self.kalman = kalman
        self.pending: deque[tuple[float, float, np.ndarray, bool, float]] = deque()  # arrival stamp z partial spread
        self.raw: np.ndarray | None = None  # latest raw measurement delivered
        self.taken = self.dropped = 0
        self.errors = EstimateErrors()
        self.carried: HeldEstimate | None = None  # while the robot holds the object
        self.seen: float | None = None  # the time the latest delivered measurement describes [s]
        self.carried_counts = [0, 0]  # gated measurements and restarts of finished holds


class FaultySensors:
    """Sensors under a ``faults:`` block (see the module doc).

    Args:
        faults: The config's faults.
        estimation: The config's estimation block.
        seed: The run's seed (every noise stream derives from it).
        wrench_sites: Names of the force/torque sensor sites (to check ``wrench.fail.site``).
        source: Where the config came from (for messages).

    Raises:
        ConfigError: ``wrench.fail.site`` is not a force/torque sensor of the scene.
    """

    def __init__(self, faults: FaultsConfig, estimation: EstimationConfig, seed: int,
                 wrench_sites: Sequence[str] = (), source: str = "<config>",
                 symmetry: Mapping[str, float] | None = None) -> None:
        self.faults, self.estimation = faults, estimation
        self.symmetry = dict(symmetry or {})  # yaw symmetry per object [rad] (0: round; 2 pi: none), for yaw errors
        self.measurer: Any = None
        """A camera (:class:`~nextage_qp.sensing.camera.source.CameraMeasurer`) measuring every object at its rate, or
        None: ``faults.object_pose``'s simulated camera (see :meth:`use_camera`)."""
        self.filter_noise = (0.0, 0.0)  # what the filter assumes of the camera's measurements [m], [rad]
        self.rng = {k: np.random.default_rng([seed, i]) for i, k in enumerate(("objects", "joints", "wrench"))}
        fail = faults.wrench.fail if faults.wrench else None
        if fail is not None and fail.site not in wrench_sites:
            raise ConfigError(f"{source}: faults.wrench.fail.site: {fail.site!r} is not a force/torque sensor; "
                              f"valid: {', '.join(wrench_sites) or '(none in this scene)'}")
        self._tracks: dict[str, _Track] = {}
        self._next_sample = 0.0
        self._joint_cache: tuple[float, np.ndarray, np.ndarray] | None = None
        self._frozen: Wrench | None = None
        self._carrier: tuple[str, Callable[[], Pose], bool] | None = None
        self.history: dict[str, list[tuple[float, np.ndarray, np.ndarray | None]]] = {}
        """Per object: (t, estimate vector, raw measurement delivered this tick or None), for logs and plots."""

    # -- objects --------------------------------------------------------------------------------------------

    def use_camera(self, measurer: Any, noise_pos_m: float, noise_rot_rad: float) -> None:
        """Measure every object with ``measurer``; the filter assumes this noise of its measurements [m], [rad]."""
        self.measurer, self.filter_noise = measurer, (noise_pos_m, noise_rot_rad)

    def _kalman(self) -> PoseKalman:
        cam, measured = self.faults.object_pose, self.measurer is not None
        noise = self.filter_noise if measured else (cam.noise_pos_m, cam.noise_rot_rad) if cam else (0.0, 0.0)
        return PoseKalman(*noise, accel_pos=self.estimation.accel_pos, accel_rot=self.estimation.accel_rot)

    def _track(self, name: str) -> _Track:
        if name not in self._tracks:
            self._tracks[name] = _Track(self._kalman() if self.estimation.object_filter == "kalman" else None)
        return self._tracks[name]

    def carry(self, name: str | None, carrier: Callable[[], Pose] | None = None, *, pushed: bool = False) -> None:
        """The object the robot now holds and the pose of what holds it (None: nothing held).

        A held object is estimated relative to its carrier (:class:`~nextage_qp.estimation.held.HeldEstimate`); when the
        hold ends the world filter restarts from that estimate. ``pushed``: the object is pushed (a contact takes it
        along the table, :class:`~nextage_qp.estimation.held.HeldEstimate`), not clamped.
        """
        self._carrier = (name, carrier, pushed) if name is not None and carrier is not None else None

    def _hold(self, t: float, name: str, tr: _Track) -> None:
        """Start, keep or end the held estimate of ``name`` at ``t`` [s] (with the Kalman filter only)."""
        entry = self._carrier if self._carrier is not None and self._carrier[0] == name else None
        k, held = tr.kalman, tr.carried
        if k is None:
            return
        if entry is not None and held is None and k.initialised:
            tr.carried = HeldEstimate(t, entry[1](), k.estimate(t), k.variance(), self._kalman(), pushed=entry[2])
        elif entry is not None and held is not None:
            held.observe(t, entry[1]())
        elif entry is None and held is not None:
            k.start(t, held.estimate(t), held.variance(t))  # as uncertain as the time unseen makes it
            tr.carried_counts = [tr.carried_counts[0] + held.kalman.rejected, tr.carried_counts[1] + held.kalman.resets]
            tr.carried = None

    def _measure(self, pose: Pose) -> np.ndarray:
        """A noisy reading (x, y, z, roll, pitch, yaw) of ``pose``: Gaussian position and rotation vector."""
        cam, rng = self.faults.object_pose, self.rng["objects"]
        assert cam is not None
        pos = pose.pos + rng.normal(0.0, cam.noise_pos_m, 3) if cam.noise_pos_m else pose.pos.copy()
        rot = pose.rot
        if cam.noise_rot_rad:
            w = rng.normal(0.0, cam.noise_rot_rad, 3)
            angle = float(np.linalg.norm(w))
            rot = axis_angle(w / angle, angle) @ rot if angle > 1e-12 else rot
        return np.concatenate([pos, rpy_of(rot)])

    def _yaw_error(self, name: str, a: float, b: float) -> float:
        """|a - b| [rad] modulo the object's yaw symmetry (0 for a round one, as in the run's metrics)."""
        return abs(wrap(a - b, self.symmetry.get(name, 2.0 * np.pi)))

    def _prior(self, name: str, t: float) -> np.ndarray | None:
        """Where the filter expects ``name`` at ``t`` [s] (None: not seen yet)."""
        tr = self._tracks.get(name)
        if tr is None or tr.raw is None:
            return None
        if tr.carried is not None:
            return tr.carried.estimate(t)
        return tr.kalman.estimate(t) if tr.kalman is not None and tr.kalman.initialised else tr.raw

    def objects(self, t: float, true: Mapping[str, Pose]) -> Mapping[str, Pose]:
        """Estimated (or latest raw) object poses at ``t`` [s]; measurements sampled, delayed, dropped here.

        With a camera (:attr:`measurer`) an object not seen yet is left out; ``true`` then only scores the
        estimates and the camera's detections (its estimator never reads it).
        """
        cam, camera = self.faults.object_pose, self.measurer
        if cam is None and camera is None:  # no camera faults: the exact poses, unfiltered
            return true
        if camera is not None:
            rate, latency = camera.rate_hz, camera.latency_s
        else:
            assert cam is not None
            rate, latency = cam.rate_hz, cam.latency_s
        sample = t + 1e-9 >= self._next_sample
        if sample:
            self._next_sample += 1.0 / rate
        seen = camera(t, {n: self._prior(n, t) for n in true},  # the objects clamped in the hands, fitted tilted
                      {n for n, tr in self._tracks.items() if tr.carried is not None and not tr.carried.pushed},
                      true) if camera is not None and sample else {}
        if sample and camera is not None and camera.skipped:  # a period the camera took no frame in
            sample = False
        out: dict[str, Pose] = {}
        for name, pose in true.items():
            tr, true_yaw = self._track(name), yaw_of(pose.rot)
            self._hold(t, name, tr)
            first = tr.raw is None and not tr.pending and camera is None
            if sample or first:
                tr.taken += 1
                if camera is not None:
                    z = seen.get(name)
                elif not first and self.rng["objects"].random() < cam.dropout:  # type: ignore[union-attr]
                    z = None
                else:
                    z = self._measure(pose)
                if z is None:
                    tr.dropped += 1
                else:
                    # The camera sees the object as it is now; the controller gets it latency_s later (the very
                    # first simulated measurement is taken to exist before the run starts).
                    view = (False, 1.0) if camera is None else (name in camera.partial, camera.spread.get(name, 1.0))
                    tr.pending.append((t if first else t + latency, t, z, *view))  # see PoseKalman.update
                    err = z[:3] - pose.pos
                    tr.errors.measurement(float(err @ err), self._yaw_error(name, z[5], true_yaw))
            delivered = None
            while tr.pending and tr.pending[0][0] <= t + 1e-9:
                _, stamp, z, partial, spread = tr.pending.popleft()
                tr.raw, tr.seen, delivered = z, stamp, z
                if tr.carried is not None:
                    tr.carried.update(stamp, z, spread)
                elif tr.kalman is not None:
                    tr.kalman.update(stamp, z, partial=partial, spread=spread)
            if tr.raw is None:  # a camera that has not seen it yet
                continue
            held = tr.raw[:3] - pose.pos
            est = (tr.carried.estimate(t) if tr.carried is not None
                   else tr.kalman.estimate(t) if tr.kalman is not None else tr.raw)
            err = est[:3] - pose.pos
            tr.errors.tick(t, float(err @ err), self._yaw_error(name, est[5], true_yaw), float(held @ held))
            self.history.setdefault(name, []).append((t, est.copy(), delivered))
            out[name] = vector_pose(est)
        return out

    def seen_at(self, name: str) -> float | None:
        """Time [s] the latest measurement of ``name`` describes: -inf before it, None when poses are the truth."""
        if self.faults.object_pose is None and self.measurer is None:
            return None
        tr = self._tracks.get(name)
        return -np.inf if tr is None or tr.seen is None else tr.seen

    def found(self, names: Sequence[str]) -> bool:
        """True once every object of ``names`` has a pose estimate."""
        return all(name in self._tracks and self._tracks[name].raw is not None for name in names)

    # -- joints and wrenches --------------------------------------------------------------------------------

    @property
    def joints_exact(self) -> bool:
        """True without ``joint_sensors`` noise."""
        return self.faults.joint_sensors is None

    def joints(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Noisy joint state; one draw per time stamp (the PD law and the phases see the same values)."""
        js = self.faults.joint_sensors
        if js is None:
            return q, qd
        if self._joint_cache is not None and self._joint_cache[0] == t:
            return self._joint_cache[1], self._joint_cache[2]
        rng = self.rng["joints"]
        qm = q + rng.normal(0.0, js.noise_rad, q.shape) if js.noise_rad else q.copy()
        qdm = qd + rng.normal(0.0, js.noise_rad_s, qd.shape) if js.noise_rad_s else qd.copy()
        self._joint_cache = (t, qm, qdm)
        return qm, qdm

    def wrenches(self, t: float, true: Mapping[str, Wrench]) -> Mapping[str, Wrench]:
        """Noisy wrenches; a failed sensor freezes at its last reading or returns NaN from ``fail.at_s`` on."""
        wf = self.faults.wrench
        if wf is None:
            return true
        rng, out = self.rng["wrench"], {}
        for name, w in true.items():
            force = w.force + rng.normal(0.0, wf.noise_n, 3) if wf.noise_n else w.force
            torque = w.torque + rng.normal(0.0, wf.noise_nm, 3) if wf.noise_nm else w.torque
            reading = Wrench(force, torque)
            if wf.fail is not None and name == wf.fail.site and t + 1e-9 >= wf.fail.at_s:
                if wf.fail.mode == "nan":
                    reading = Wrench(np.full(3, np.nan), np.full(3, np.nan))
                else:
                    self._frozen = self._frozen or reading
                    reading = self._frozen
            out[name] = reading
        return out

    # -- report ---------------------------------------------------------------------------------------------

    def report(self, shoves: Sequence[tuple[str, float, float]] = ()) -> dict[str, Any]:
        """Estimation errors against the truth per object (see :class:`~nextage_qp.estimation.report.EstimateErrors`).

        ``shoves``: (body, start, end) [s] of the shoves (:meth:`~nextage_qp.sensing.shoves.Shoves.windows`) left out of
        ``estimate_outside_shoves_rms_m``; a robot camera's frames give ``estimate_unoccluded_rms_m`` (its views).
        """
        objects = {}
        for name, tr in self._tracks.items():
            k, c = tr.kalman, tr.carried
            spans = [(a, b) for body, a, b in shoves if body == name]
            objects[name] = {
                **tr.errors.report(spans, self.measurer.views.get(name) if self.measurer is not None else None),
                "measurements": tr.taken, "dropouts": tr.dropped,
                "rejected": (k.rejected if k else 0) + tr.carried_counts[0] + (c.kalman.rejected if c else 0),
                "filter_resets": (k.resets if k else 0) + tr.carried_counts[1] + (c.kalman.resets if c else 0),
            }
        out = {"object_filter": self.estimation.object_filter, "objects": objects}
        if self.measurer is not None:
            out["camera"] = self.measurer.report()
        return out
