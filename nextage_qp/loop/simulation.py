r"""The control loop: Ruckig references at ``ctrl_dt``, PD torques at every ``sim_dt`` physics step, a recorder.

One :meth:`Simulation.tick` is one control period (``Timing.ctrl_dt``): Ruckig advances the joint
reference to the end of the period, then ``n_substeps = ctrl_dt / sim_dt`` MuJoCo steps follow, each with a
fresh torque from the PD law evaluated inside MuJoCo on the state of that step:

.. math:: u_k = \operatorname{clip}(K_p(q^{ref}(t_k) - q_k) + K_d(\dot q^{ref}(t_k) - \dot q_k) + b)

The law runs in MuJoCo's actuators (:meth:`~nextage_qp.loop.pd.PDController.install`): the loop sets one control
vector per step, ramped linearly from the reference at the start of the period to the one at its end (the
first-order hold of Ruckig's smooth profile; the bias :math:`b` is sampled once per period), and ``mj_step``
applies the feedback and the clamp; under the ``implicitfast`` integrator the damping term is integrated
implicitly, so stiff ``kd`` does not destabilise the loop.

What the controller sees passes through one seam, :class:`Sensors`: the joint state the PD law uses and the
:class:`Measurement` the phases read after every tick (with a mobile robot's odometry, and objects in its world).
Every tick is recorded; the ``substep_hooks`` see every physics step. A NaN or a joint faster than ``max_speed``
stops the loop with a :class:`~nextage_qp.errors.SimulationError` naming the time and joint.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from nextage_qp.errors import SimulationError
from nextage_qp.loop import stepping
from nextage_qp.loop.divergence import divergence_message
from nextage_qp.loop.pd import ActuatorBlock, Gains, PDController, index_view
from nextage_qp.loop.recorder import FrameRows, Recorder, StageTimer
from nextage_qp.loop.reference import JointTrajectory, RefState, TrajectoryLimits, cap_velocity
from nextage_qp.loop.timing import Timing
from nextage_qp.mobile.odometry import BaseTrack
from nextage_qp.native.mj_warnings import MUJOCO_WARNINGS
from nextage_qp.robots.model import Robot
from nextage_qp.sensing.sensors import Measurement, PerfectSensors, Pose, Sensors, SensorWatch, WrenchSensor

__all__ = ["Hook", "Simulation", "StageTimer", "Timing"]

Hook = Callable[["Simulation"], None]
_BAD = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


class Simulation:
    """The Nextage in MuJoCo under Ruckig-referenced joint PD control.

    Args:
        robot: Robot and scene (the model's timestep is set to ``timing.sim_dt``).
        gains: PD gains.
        limits: Velocity, acceleration and jerk bounds of the reference.
        timing: Physics step and control period.
        frames: Sites or bodies whose world pose is recorded every step.
        max_speed: A joint faster than this [rad/s] counts as divergence.
        sensors: What the controller sees (default: perfect).

    Attributes:
        data: The MuJoCo state.
        traj: The online reference generator.
        pd: The PD torque law (holds the saturation counters).
        recorder: The log of the run.
        measured: The :class:`Measurement` after the last tick.
        hooks: Functions called as ``hook(sim)`` after every tick (e.g. to measure clearances).
        substep_hooks: Functions called as ``hook(sim)`` at every physics step, after its contacts.
        timer: A :class:`StageTimer` to profile the loop, or None.
        physics_s: Wall time inside ``mj_step`` since the last :meth:`reset` [s] (timed where it is called).
        touch_adr: ``sensordata`` address of a contact sensor's (found, dist) read every step (-1: none).
        touch_steps: Physics steps after which that sensor read a touch, since the last :meth:`reset`.
        base: A mobile robot's base (:class:`~nextage_qp.mobile.base.BaseTrack`), or None.
    """

    def __init__(
        self,
        robot: Robot,
        gains: Gains,
        limits: TrajectoryLimits | None = None,
        *,
        timing: Timing | None = None,
        frames: Sequence[str] = (),
        max_speed: float = 50.0,
        sensors: Sensors | None = None,
    ) -> None:
        self.timing = timing or Timing()
        self.robot, self.model = robot, robot.model
        self.model.opt.timestep = self.timing.sim_dt
        # Keep NaNs visible (MuJoCo would otherwise silently reset the state) so divergence is reported.
        self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        self.sim_dt, self.ctrl_dt, self.n_substeps = self.timing.sim_dt, self.timing.ctrl_dt, self.timing.n_substeps
        self.max_speed = max_speed
        self.data = mujoco.MjData(self.model)
        self.pd = PDController(gains, robot.torque_limit)
        self.pd.install(self.model, robot.actuator_ids)
        self.limits = cap_velocity(limits or TrajectoryLimits(), robot.joint_names, robot.velocity_limit)
        self.traj = JointTrajectory(self.limits, dt=self.ctrl_dt, lower=robot.lower, upper=robot.upper,
                                    joint_names=robot.joint_names)
        self.sensors: Sensors = sensors or PerfectSensors()
        self._perfect = sensors is None or isinstance(sensors, PerfectSensors)
        self.frames = tuple(robot.frame(f) for f in frames)
        self._frame_poses = FrameRows(self.frames, self.data)
        self.wrench_sensors, self.watch = WrenchSensor.of_model(self.model), SensorWatch()
        self.objects = tuple((name, robot.object_qpos_slice(name), robot.model.body(name).id)
                             for name in robot.object_names)
        self.recorder = Recorder(robot.joint_names, tuple(frames), tuple(n for n, _, _ in self.objects),
                                 sim_dt=self.sim_dt, ctrl_dt=self.ctrl_dt)
        self.hooks: list[Hook] = []
        self.substep_hooks: list[Hook] = []
        self.timer: StageTimer | None = None
        self.touch_adr, self.touch_steps = -1, 0
        # Views into MjData (the robot's joints are contiguous in every bundled scene; an index array otherwise;
        # its actuators a block of any order) and per-tick buffers, so the loop allocates little.
        self._qi, self._di = index_view(robot.qpos_idx), index_view(robot.dof_idx)
        self._act = ActuatorBlock(robot.actuator_ids, self.data)
        self._bad_warnings = [self.data.warning[w] for w in _BAD]  # views into the data
        self.base = BaseTrack(robot.base) if robot.base is not None else None
        self._fractions = np.arange(self.n_substeps) / self.n_substeps
        self._force = np.zeros((self.n_substeps, self._act.width))
        if stepping.NATIVE:  # load (or compile) the loop now, with the types a tick passes: no tick pays for it
            stepping.substeps(stepping.STEP, 0, 0, self._act.ctrl, self._force[:0], self._act.force, self._force,
                              self.data.sensordata, -1)
        self._raw: RefState | None = None
        self._step = 0
        self.physics_s = 0.0
        self.reset(robot.keyframe_q("home"))

    @property
    def time(self) -> float:
        """Simulated time since the last :meth:`reset` [s]."""
        return self._step * self.sim_dt

    @property
    def q(self) -> np.ndarray:
        """True joint positions [rad] (the controller sees :attr:`measured`)."""
        return self.robot.get_q(self.data)

    @property
    def qd(self) -> np.ndarray:
        """True joint velocities [rad/s]."""
        return self.robot.get_qd(self.data)

    @property
    def ref(self) -> RefState:
        """The joint reference at the end of the last tick."""
        return self._raw if self._raw is not None else self.traj.state

    def object_poses(self) -> dict[str, Pose]:
        """True world pose of every free object."""
        d = self.data
        return {name: Pose(d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy()) for name, _, b in self.objects}

    def _measure(self) -> None:
        t, sensors = self.time, self.sensors
        q, qd = sensors.joints(t, self.q, self.qd)
        wrenches = sensors.wrenches(t, {w.name: w.read(self.data) for w in self.wrench_sensors})
        if not self._perfect:  # the simulator's own readings neither fail nor freeze: only faulty sensors do
            self.watch.check(t, wrenches)
        objects, base = sensors.objects(t, self.object_poses()), None
        if self.base is not None:  # odometry; the objects as the robot's own sensors see them, in its world
            base, objects = self.base.observe(self.data, t, objects)
        self.measured = Measurement(t, q, qd, objects, wrenches, base)

    def reset(self, q0: np.ndarray) -> None:
        """Robot at rest at ``q0`` [rad], objects at their scene start poses, empty log, reference = ``q0``."""
        mujoco.mj_resetData(self.model, self.data)
        MUJOCO_WARNINGS.clear()  # a failure quotes the first warning of its own run
        self.robot.set_q(self.data, np.asarray(q0, dtype=float))
        mujoco.mj_forward(self.model, self.data)
        self.traj.reset(q0)
        self.pd.reset_counters()
        self.watch.reset()
        self.recorder.clear()
        self._raw, self._step, self.physics_s, self.touch_steps = None, 0, 0.0, 0
        if self.base is not None:
            self.base.reset(self.model, self.data)
        self._measure()

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
        m, d, timer, n = self.model, self.data, self.timer, self.n_substeps
        if timer:
            timer.start()
        raw = self._raw
        start = raw if raw is not None else self.traj.state
        end = raw if raw is not None else self.traj.update()
        if timer:
            timer.lap("ruckig")
        q, qd = d.qpos[self._qi], d.qvel[self._di]
        bias = d.qfrc_bias[self._di]
        if self._perfect:
            offsets: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        else:
            qm, qdm = self.sensors.joints(self.time, q.copy(), qd.copy())
            offsets = (q - qm, qd - qdm)
        # The actuators' control ramps linearly from the reference at the start of the tick to the one at its
        # end (Ruckig's profile is smooth: within 4 ms the ramp is its first-order hold); bias and sensor offsets
        # are held over the tick.
        c0 = self.pd.ctrl(start.q, start.qd, bias, *offsets)
        c1 = c0 if end is start else self.pd.ctrl(end.q, end.qd, bias, *offsets)
        ramp = np.multiply.outer(self._fractions, c1 - c0)
        ramp += c0
        ramp = self._act.spread(ramp)  # into the actuators' order
        self.recorder.record(self.time, q, qd, start.q, start.qd, None, self._frame_poses(), self._object_rows())
        if timer:
            timer.lap("pd+record")
        ctrl, act_force, force, hooks = self._act.ctrl, self._act.force, self._force, self.substep_hooks
        clock, touch = time.perf_counter, self.touch_adr
        if hooks or not stepping.NATIVE:
            step, physics = mujoco.mj_step, 0.0
            for k in range(n):
                ctrl[:] = ramp[k]
                t0 = clock()
                step(m, d)
                physics += clock() - t0
                force[k] = act_force
                self._step += 1
                self.touch_steps += touch >= 0 and stepping.touching(d.sensordata, touch)
                for hook in tuple(hooks):
                    hook(self)
        else:  # the same loop compiled: timed as a whole, its own work a few copies per step
            t0 = clock()
            self.touch_steps += stepping.substeps(stepping.STEP, m._address, d._address, ctrl, ramp, act_force, force,
                                                  d.sensordata, touch)
            physics = clock() - t0
            self._step += n
        self.physics_s += physics
        if timer:
            timer.lap("physics")
        force = self._act.joint_order(force)
        self.pd.count(force)
        self.recorder.set_last("tau", force[0])
        self._check()
        self._measure()
        for hook in self.hooks:
            hook(self)
        if timer:
            timer.lap("measure+hooks")

    def run(self, duration: float) -> None:
        """Tick until ``duration`` [s] more of simulated time has passed."""
        end = self._step + round(duration / self.sim_dt)
        while self._step < end:
            self.tick()

    def _object_rows(self) -> list[np.ndarray]:
        return [self.data.qpos[s] for _, s, _ in self.objects]

    def _check(self) -> None:
        d = self.data
        # Fast path: a NaN fails both comparisons below, so only a healthy state returns here.
        if not any(w.number for w in self._bad_warnings) and np.abs(d.qvel[self._di]).max() <= self.max_speed \
                and np.isfinite(d.qpos).all():
            return
        bad_warn = any(w.number for w in self._bad_warnings)
        msg = divergence_message(self.robot.joint_names, self.time, d.qpos[self.robot.qpos_idx],
                                 d.qvel[self.robot.dof_idx], self.recorder.recent(1), max_speed=self.max_speed,
                                 sim_dt=self.sim_dt, warnings=MUJOCO_WARNINGS if bad_warn else ())
        self.recorder.meta["error"] = msg
        raise SimulationError(msg)
