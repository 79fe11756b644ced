r"""The control loop: Ruckig references at ``ctrl_dt``, PD torques at every ``sim_dt`` physics step, a recorder.

One :meth:`Simulation.tick` is one control period (default 4 ms = 250 Hz): Ruckig advances the joint
reference towards the latest target, then ``n_substeps = ctrl_dt / sim_dt`` MuJoCo steps follow, each
with a fresh torque from the PD law evaluated on the state at that step and the Ruckig reference sampled
at the same instant:

.. math:: u_k = \operatorname{clip}(K_p(q^{ref}(t_k) - q_k) + K_d(\dot q^{ref}(t_k) - \dot q_k) + b(q_k, \dot q_k))

Every physics step is recorded (time [s], q [rad], q̇ [rad/s], q_ref, q̇_ref, torque [N·m], chosen frame
poses and free-object poses). A NaN or a joint faster than ``max_speed`` stops the loop with a
:class:`~nextage_qp.errors.SimulationError` naming the time and joint; the caller still saves the log.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from nextage_qp.control import Gains, PDController
from nextage_qp.errors import SimulationError
from nextage_qp.robot import JOINT_NAMES, Robot
from nextage_qp.trajectory import JointTrajectory, RefState, TrajectoryLimits

Hook = Callable[["Simulation"], None]
_BAD = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


class Recorder:
    """Per-physics-step log of the loop, growing in chunks; saved as ``.npz`` plus a ``.json`` summary.

    Arrays in the ``.npz``: ``t`` [s] (k,), ``q``, ``qd``, ``q_ref``, ``qd_ref`` [rad, rad/s] and ``tau``
    [N·m] (k, 15), ``frame_<name>`` and ``object_<name>`` (k, 7: position [m], quaternion w x y z), and for
    every signal added with :meth:`add` ``extra_<name>`` (m, ...) with its times ``extra_<name>_t``.

    Attributes:
        meta: Free-form facts merged into the JSON summary (e.g. ``error``, the target).
    """

    def __init__(self, frames: Sequence[str], objects: Sequence[str], *, sim_dt: float, ctrl_dt: float) -> None:
        n = len(JOINT_NAMES)
        self.frames, self.objects = tuple(frames), tuple(objects)
        self._dims = {"t": 1, "q": n, "qd": n, "q_ref": n, "qd_ref": n, "tau": n}
        self._dims |= {f"frame_{f}": 7 for f in self.frames} | {f"object_{o}": 7 for o in self.objects}
        self._timing = {"sim_dt": sim_dt, "ctrl_dt": ctrl_dt}
        self.clear()

    def clear(self) -> None:
        """Drop everything recorded."""
        self._n = 0
        self._buf = {k: np.empty((4096, dim)) for k, dim in self._dims.items()}
        self._extra: dict[str, tuple[list[float], list[Any]]] = {}
        self.meta: dict[str, Any] = {}

    def __len__(self) -> int:
        return self._n

    def record(self, t: float, *rows: Any) -> None:
        """Append one step: time, q, qd, q_ref, qd_ref, tau, a list of frame poses, a list of object poses."""
        if self._n == len(self._buf["t"]):
            self._buf = {k: np.concatenate([b, np.empty_like(b)]) for k, b in self._buf.items()}
        i, buf = self._n, self._buf
        buf["t"][i, 0] = t
        for key, row in zip(("q", "qd", "q_ref", "qd_ref", "tau"), rows[:5], strict=True):
            buf[key][i] = row
        for name, pose in zip(self.frames, rows[5], strict=True):
            buf[f"frame_{name}"][i] = pose
        for name, pose in zip(self.objects, rows[6], strict=True):
            buf[f"object_{name}"][i] = pose
        self._n += 1

    def add(self, name: str, t: float, value: Any) -> None:
        """Append an extra signal sample (e.g. from a hook): ``extra_<name>`` at time ``t`` [s]."""
        ts, values = self._extra.setdefault(name, ([], []))
        ts.append(t)
        values.append(np.asarray(value, dtype=float))

    def recent(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last ``n`` steps' time [s], q [rad] and qd [rad/s] (views, no copy)."""
        lo = max(0, self._n - n)
        b = self._buf
        return b["t"][lo : self._n, 0], b["q"][lo : self._n], b["qd"][lo : self._n]

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything recorded so far, as arrays (``t`` is 1-D)."""
        out = {k: b[: self._n].copy() for k, b in self._buf.items()}
        out["t"] = out["t"][:, 0]
        for name, (ts, values) in self._extra.items():
            out[f"extra_{name}"], out[f"extra_{name}_t"] = np.asarray(values), np.asarray(ts)
        return out

    def summary(self) -> dict[str, Any]:
        """Key figures of the run: duration, peak torques, peak tracking errors, final state, plus ``meta``."""
        a = self.arrays()
        out: dict[str, Any] = {"samples": self._n, **self._timing, "frames": list(self.frames)}
        if self._n:
            err = np.abs(a["q_ref"] - a["q"])
            out |= {
                "duration_s": float(a["t"][-1] + self._timing["sim_dt"]),
                "max_abs_torque_nm": dict(zip(JOINT_NAMES, np.abs(a["tau"]).max(0).round(4).tolist(), strict=True)),
                "max_tracking_error_rad": dict(zip(JOINT_NAMES, err.max(0).round(6).tolist(), strict=True)),
                "final_q": dict(zip(JOINT_NAMES, a["q"][-1].round(6).tolist(), strict=True)),
                "final_frames": {f: a[f"frame_{f}"][-1].round(6).tolist() for f in self.frames},
                "final_objects": {o: a[f"object_{o}"][-1].round(6).tolist() for o in self.objects},
            }
        return out | self.meta

    def save(self, npz_path: str | Path) -> Path:
        """Write ``npz_path`` (arrays) and the same name with ``.json`` (summary); returns the JSON path."""
        path = Path(npz_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        savez: Any = np.savez_compressed  # numpy's stub mistypes **arrays
        savez(path, **self.arrays())
        js = path.with_suffix(".json")
        js.write_text(json.dumps(self.summary(), indent=2, default=str) + "\n")
        return js


class Simulation:
    """The Nextage in MuJoCo under Ruckig-referenced joint PD control.

    Args:
        robot: Robot and scene (the model's timestep is set to ``sim_dt``).
        gains: PD gains.
        limits: Velocity, acceleration and jerk bounds of the reference.
        sim_dt: Physics step [s].
        ctrl_dt: Control period [s], an integer multiple of ``sim_dt``.
        frames: Sites or bodies whose world pose is recorded every step.
        max_speed: A joint faster than this [rad/s] counts as divergence.

    Attributes:
        data: The MuJoCo state.
        traj: The online reference generator.
        pd: The PD torque law (holds the saturation counters).
        recorder: The log of the run.
        hooks: Functions called as ``hook(sim)`` after every tick (e.g. to measure clearances).
        substep_hooks: Functions called as ``hook(sim)`` at every physics step, once its contacts are
            computed (e.g. to count steps with a contact).
        tau_ff: Optional feed-forward torque [N·m], added to every PD torque while set.
    """

    def __init__(
        self,
        robot: Robot,
        gains: Gains,
        limits: TrajectoryLimits | None = None,
        *,
        sim_dt: float = 0.001,
        ctrl_dt: float = 0.004,
        frames: Sequence[str] = ("left_wrist", "right_wrist"),
        max_speed: float = 50.0,
    ) -> None:
        n_sub = round(ctrl_dt / sim_dt)
        if sim_dt <= 0 or n_sub < 1 or abs(n_sub * sim_dt - ctrl_dt) > 1e-12:
            raise SimulationError(f"ctrl_dt={ctrl_dt} s must be a positive integer multiple of sim_dt={sim_dt} s")
        self.robot, self.model = robot, robot.model
        self.model.opt.timestep = sim_dt
        # Keep NaNs visible (MuJoCo would otherwise silently reset the state) so divergence is reported.
        self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        self.sim_dt, self.ctrl_dt, self.n_substeps = sim_dt, ctrl_dt, n_sub
        self.max_speed = max_speed
        self.data = mujoco.MjData(self.model)
        self.pd = PDController(gains, robot.torque_limit)
        self.limits = limits or TrajectoryLimits()
        self.traj = JointTrajectory(self.limits, dt=ctrl_dt, lower=robot.lower, upper=robot.upper)
        self.frames = tuple(robot.frame(f) for f in frames)
        self.objects = tuple((name, robot.object_qpos_slice(name)) for name in robot.object_names)
        self.recorder = Recorder(tuple(frames), tuple(n for n, _ in self.objects), sim_dt=sim_dt, ctrl_dt=ctrl_dt)
        self.hooks: list[Hook] = []
        self.substep_hooks: list[Hook] = []
        self.tau_ff: np.ndarray | None = None
        self._raw: RefState | None = None
        self._step = 0
        self.reset(robot.keyframe_q("home"))

    @property
    def time(self) -> float:
        """Simulated time since the last :meth:`reset` [s]."""
        return self._step * self.sim_dt

    @property
    def q(self) -> np.ndarray:
        """Joint positions [rad]."""
        return self.robot.get_q(self.data)

    @property
    def qd(self) -> np.ndarray:
        """Joint velocities [rad/s]."""
        return self.robot.get_qd(self.data)

    @property
    def ref(self) -> RefState:
        """The joint reference at the end of the last tick."""
        return self._raw if self._raw is not None else self.traj.state

    def reset(self, q0: np.ndarray) -> None:
        """Robot at rest at ``q0`` [rad], objects at their scene start poses, empty log, reference = ``q0``."""
        mujoco.mj_resetData(self.model, self.data)
        self.robot.set_q(self.data, np.asarray(q0, dtype=float))
        mujoco.mj_forward(self.model, self.data)
        self.traj.reset(q0)
        self.pd.reset_counters()
        self.recorder.clear()
        self._raw, self._step = None, 0

    def set_target(self, q_des: np.ndarray, qd_des: np.ndarray | None = None, *, shaped: bool = True) -> None:
        """New joint target [rad] (and velocity [rad/s]); Ruckig re-plans on the next tick.

        With ``shaped=False`` the reference jumps to the target at once (a raw step, as in the report's PD
        test) and Ruckig is bypassed until the next shaped target, which starts from that step.
        """
        if shaped:
            if self._raw is not None:
                self.traj.reset(self._raw.q, self._raw.qd)
                self._raw = None
            self.traj.set_target(q_des, qd_des)
        else:
            qd = np.zeros(self.robot.nq) if qd_des is None else np.asarray(qd_des, dtype=float)
            self._raw = RefState(np.asarray(q_des, dtype=float).copy(), qd, np.zeros(self.robot.nq))

    def tick(self) -> None:
        """One control period: a reference update, then ``n_substeps`` physics steps with fresh PD torques.

        Raises:
            SimulationError: The state became NaN or a joint exceeded ``max_speed``.
            TrajectoryError: Ruckig rejected the target.
        """
        m, d, r, rec = self.model, self.data, self.robot, self.recorder
        qi, di, ai = r.qpos_idx, r.dof_idx, r.actuator_ids
        raw = self._raw
        if raw is None:
            self.traj.update()
        for k in range(self.n_substeps):
            ref = raw if raw is not None else self.traj.interpolate(k * self.sim_dt)
            mujoco.mj_step1(m, d)
            for hook in self.substep_hooks:
                hook(self)
            q, qd = d.qpos[qi], d.qvel[di]
            tau = self.pd.torque(q, qd, ref.q, ref.qd, d.qfrc_bias[di], self.tau_ff)
            d.ctrl[ai] = tau
            rec.record(self.time, q, qd, ref.q, ref.qd, tau, self._frame_poses(), self._object_poses())
            mujoco.mj_step2(m, d)
            self._step += 1
        self._check()
        for hook in self.hooks:
            hook(self)

    def run(self, duration: float) -> None:
        """Tick until ``duration`` [s] more of simulated time has passed."""
        end = self._step + round(duration / self.sim_dt)
        while self._step < end:
            self.tick()

    def _frame_poses(self) -> list[np.ndarray]:
        d, out = self.data, []
        for kind, fid in self.frames:
            quat = np.empty(4)
            if kind == "site":
                mujoco.mju_mat2Quat(quat, d.site_xmat[fid])
                out.append(np.concatenate([d.site_xpos[fid], quat]))
            else:
                out.append(np.concatenate([d.xpos[fid], d.xquat[fid]]))
        return out

    def _object_poses(self) -> list[np.ndarray]:
        return [self.data.qpos[s] for _, s in self.objects]

    def _check(self) -> None:
        d = self.data
        q, qd = d.qpos[self.robot.qpos_idx], d.qvel[self.robot.dof_idx]
        bad_warn = any(d.warning[w].number for w in _BAD)
        finite = np.isfinite(q) & np.isfinite(qd)
        fast = np.abs(np.nan_to_num(qd, nan=np.inf)) > self.max_speed
        if not (bad_warn or not finite.all() or fast.any() or not np.all(np.isfinite(d.qpos))):
            return
        t = self.time
        if not finite.all():
            # NaN spreads to every joint within a step: name the first joint that went bad in this tick.
            ts, qs, qds = self.recorder.recent(self.n_substeps)
            bad_rows = np.flatnonzero(~(np.isfinite(qs) & np.isfinite(qds)).all(axis=1))
            if bad_rows.size:
                t, q, qd = float(ts[bad_rows[0]]), qs[bad_rows[0]], qds[bad_rows[0]]
                finite = np.isfinite(q) & np.isfinite(qd)
            j = int(np.flatnonzero(~finite)[0])
            what = f"joint {JOINT_NAMES[j]} state is not finite (q={q[j]}, qd={qd[j]})"
        elif fast.any():
            j = int(np.argmax(np.abs(qd)))
            what = f"joint {JOINT_NAMES[j]} velocity {qd[j]:.3g} rad/s exceeds {self.max_speed:g} rad/s"
        else:
            what = "MuJoCo reported a bad position, velocity or acceleration (an object's state is not finite)"
        msg = f"t={t:.3f} s: {what}; the simulation diverged (gains too stiff for sim_dt={self.sim_dt} s?)"
        self.recorder.meta["error"] = msg
        raise SimulationError(msg)
