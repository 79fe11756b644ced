"""A run as a Rerun recording (``run --rerun out.rrd``): the scene in 3-D and every signal on one timeline.

While the run goes, an ``on_tick`` hook keeps only what the run's own recorder does not: the commanded joints,
the contact forces on the task's object, the phases and a mobile base's pose (a few small copies per tick). When it
ends, everything is written at once, column by column (``rerun.send_columns``), so the recording costs little wall
time:

* ``world/...``: every body with geoms, its boxes, spheres, capsules, cylinders, ellipsoids and meshes logged once
  in the body's frame, and its pose at every frame (recomputed from the recorded joints and object poses);
* ``tools/FRAME/measured`` and ``tools/FRAME/commanded``: the robot's tool and pad frames, as the simulation has them
  and where the IK sends them;
* ``joints/NAME/q``, ``q_ref``, ``q_cmd``, ``tau``: positions against their references and commands, torques;
* ``contacts/OBJECT``: the contact forces on the task's object, as arrows at the contact points;
* ``objects/NAME/truth`` and ``objects/NAME/estimate``: the objects' true positions and what the controller saw;
* ``phases``: the phases as a text log (and ``phases/index`` as a step signal);
* ``base/true`` and ``base/odometry``: a mobile base's path;
* ``camera/NAME/depth``: the depth images of the robot's camera, where one runs (``perception.source: camera``).

Nothing here starts the Rerun viewer or connects anywhere: the file is written locally (``rerun out.rrd`` opens it).
"""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner

TIMELINE = "sim_time"
"""The recording's timeline: simulated time [s]."""
FORCE_SCALE = 0.01
"""Length [m] of a contact force arrow per newton."""
IMAGE_HZ = 2.0
"""Depth images per simulated second kept from a robot camera that runs."""


def _rerun() -> Any:
    try:
        import rerun
    except ImportError:
        raise ConfigError("--rerun needs the Rerun SDK: pip install -e '.[rerun]' (or pip install rerun-sdk)") from None
    return rerun


class RerunRecording:
    """Collects a run's extra signals tick by tick (:meth:`on_tick`) and writes the recording (:meth:`close`).

    Args:
        runner: The run (not started).
        path: The ``.rrd`` file to write.
        fps: Frames per simulated second of the 3-D scene (the signals keep every tick).
    """

    def __init__(self, runner: Runner, path: Path, *, fps: float = 25.0) -> None:
        self.rr = _rerun()
        self.runner, self.path, self.period = runner, Path(path), 1.0 / fps
        self.t: list[float] = []
        self.q_cmd: list[np.ndarray] = []
        self.contacts: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.phases: list[tuple[float, str]] = []
        self._phase: str | None = "start"
        self._next_contact = self._next_image = 0.0
        self.images: list[tuple[float, np.ndarray]] = []
        model = runner.robot.model
        obj = runner.cfg.object
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, obj)
        self._object = bid if bid >= 0 else None

    def on_tick(self, runner: Runner, phase: Any) -> None:
        """Tick callback: keep the commanded joints, the object's contact forces and phase changes."""
        t = runner.sim.time
        self.t.append(t)
        self.q_cmd.append(np.array(runner.servo.q_cmd))
        camera = getattr(runner.camera, "last", None)  # the robot's camera, where one runs: depth at IMAGE_HZ
        if camera is not None and camera[0] >= self._next_image:
            self._next_image = camera[0] + 1.0 / IMAGE_HZ
            self.images.append((camera[0], np.array(camera[1], dtype=np.float32)))
        name = None if phase is None else phase.name
        if name != self._phase:
            self.phases.append((t, name or "settle"))
            self._phase = name
        if self._object is not None and t + 1e-9 >= self._next_contact:  # contacts at the scene's frame rate
            self._next_contact = t + self.period
            m, d = runner.robot.model, runner.sim.data
            force = np.zeros(6)
            for i in range(d.ncon):
                c = d.contact[i]
                b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
                if self._object not in (b1, b2):
                    continue
                mujoco.mj_contactForce(m, d, i, force)
                world = c.frame.reshape(3, 3).T @ force[:3]  # the force geom1's body exerts on geom2's
                self.contacts.append((t, c.pos.copy(), world if b2 == self._object else -world))

    def close(self) -> None:
        """Write the recording.

        Raises:
            OSError: The file cannot be written.
        """
        rr = self.rr
        rec = rr.RecordingStream("nextage_qp", recording_id=uuid.uuid4())
        rec.send_recording_name(self.runner.cfg.task)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rec.save(str(self.path))
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        runner = self.runner
        rec_arrays = runner.sim.recorder.arrays()
        times = rec_arrays["t"]
        if not len(times):
            return rec.flush()
        idx = [rr.TimeColumn(TIMELINE, duration=times)]
        names = runner.robot.joint_names
        for j, name in enumerate(names):
            for key, values in (("q", rec_arrays["q"][:, j]), ("q_ref", rec_arrays["q_ref"][:, j]),
                                ("tau", rec_arrays["tau"][:, j])):
                rec.send_columns(f"joints/{name}/{key}", indexes=idx, columns=rr.Scalars.columns(scalars=values))
        if self.q_cmd:
            cmd, tc = np.array(self.q_cmd), [rr.TimeColumn(TIMELINE, duration=np.array(self.t))]
            for j, name in enumerate(names):
                rec.send_columns(f"joints/{name}/q_cmd", indexes=tc, columns=rr.Scalars.columns(scalars=cmd[:, j]))
        self._scene(rec, rec_arrays)
        self._tools(rec, rec_arrays)
        self._objects(rec, rec_arrays, idx)
        for t, name in self.phases:
            rec.set_time(TIMELINE, duration=t)
            rec.log("phases", rr.TextLog(f"phase: {name}", level="INFO"))
        if self.phases:
            steps = np.searchsorted([t for t, _ in self.phases], times, side="right") - 1
            rec.send_columns("phases/index", indexes=idx, columns=rr.Scalars.columns(scalars=steps.astype(float)))
        if self.contacts:  # one batch of arrows per frame, all frames in one column
            ts = np.array([t for t, _, _ in self.contacts])
            frames, counts = np.unique(ts, return_counts=True)
            rec.send_columns(f"contacts/{runner.cfg.object}", indexes=[rr.TimeColumn(TIMELINE, duration=frames)],
                             columns=rr.Arrows3D.columns(
                                 origins=np.array([p for _, p, _ in self.contacts]),
                                 vectors=np.array([f for _, _, f in self.contacts]) * FORCE_SCALE).partition(counts))
        for t, depth in self.images:
            rec.set_time(TIMELINE, duration=t)
            rec.log(f"camera/{runner.cfg.perception.camera}/depth", rr.DepthImage(depth, meter=1.0))
        if runner.sim.base is not None and runner.sim.base.log:
            base = np.array(runner.sim.base.log)
            bt = [rr.TimeColumn(TIMELINE, duration=base[:, 0])]
            for label, cols in (("true", slice(1, 3)), ("odometry", slice(4, 6))):
                xyz = np.c_[base[:, cols], np.zeros(len(base))]
                rec.send_columns(f"base/{label}", indexes=bt, columns=rr.Points3D.columns(positions=xyz))
        rec.flush()

    def _scene(self, rec: Any, arrays: dict[str, np.ndarray]) -> None:
        """Every body's geoms once, in its frame; its world pose at every scene frame."""
        rr, runner = self.rr, self.runner
        m = runner.robot.model
        shown = [g for g in range(m.ngeom) if m.geom_group[g] < 3 and m.geom_rgba[g, 3] > 0]
        bodies = sorted({int(m.geom_bodyid[g]) for g in shown})
        for b in bodies:
            geoms = [g for g in shown if int(m.geom_bodyid[g]) == b]
            _log_geoms(rr, rec, f"world/{_body_name(m, b)}", m, geoms)
        # the poses: replay the recorded joints and objects through the model's kinematics, at the scene's rate
        d = mujoco.MjData(m)
        times = arrays["t"]
        pick = [0]
        for k, t in enumerate(times):
            if t >= times[pick[-1]] + self.period - 1e-9:
                pick.append(k)
        base = np.array(runner.sim.base.log) if runner.sim.base is not None and runner.sim.base.log else None
        poses = np.empty((len(pick), len(bodies), 7))
        for i, k in enumerate(pick):
            runner.robot.set_q(d, arrays["q"][k])
            for name, sl, _ in runner.sim.objects:
                d.qpos[sl] = arrays[f"object_{name}"][k]
            if base is not None and runner.robot.base is not None:
                runner.robot.base.place(d, base[min(k, len(base) - 1), 1:4])
            mujoco.mj_kinematics(m, d)
            poses[i, :, :3] = d.xpos[bodies]
            poses[i, :, 3:] = d.xquat[bodies][:, [1, 2, 3, 0]]  # rerun: x, y, z, w
        idx = [rr.TimeColumn(TIMELINE, duration=times[pick])]
        for j, b in enumerate(bodies):
            if m.body_weldid[b] == 0 and m.body_mocapid[b] < 0:  # fixed to the world: once
                rec.log(f"world/{_body_name(m, b)}", rr.Transform3D(translation=poses[0, j, :3],
                                                                   quaternion=poses[0, j, 3:]), static=True)
                continue
            rec.send_columns(f"world/{_body_name(m, b)}", indexes=idx,
                             columns=rr.Transform3D.columns(translation=poses[:, j, :3], quaternion=poses[:, j, 3:]))

    def _tools(self, rec: Any, arrays: dict[str, np.ndarray]) -> None:
        """The robot's tool and pad frames: measured (recorded) and commanded (FK of the commanded joints)."""
        rr, runner = self.rr, self.runner
        idx = [rr.TimeColumn(TIMELINE, duration=arrays["t"])]
        for frame in runner.sim.recorder.frames:
            key = f"frame_{frame}"
            if key in arrays:
                rec.send_columns(f"tools/{frame}/measured", indexes=idx,
                                 columns=rr.Points3D.columns(positions=arrays[key][:, :3]))
        if not self.q_cmd:
            return
        cmd = np.array(self.q_cmd)
        step = max(1, round(self.period / runner.sim.ctrl_dt))
        rows = range(0, len(cmd), step)
        for frame in runner.sim.recorder.frames:
            pos = np.array([runner.servo.pose_at(frame, cmd[k]).pos for k in rows])
            rec.send_columns(f"tools/{frame}/commanded", indexes=[rr.TimeColumn(TIMELINE, duration=np.array(
                self.t)[list(rows)])], columns=rr.Points3D.columns(positions=pos))

    def _objects(self, rec: Any, arrays: dict[str, np.ndarray], idx: list[Any]) -> None:
        """The objects' true positions, and the controller's estimates where perception estimated them."""
        rr, runner = self.rr, self.runner
        for name in runner.robot.object_names:
            rec.send_columns(f"objects/{name}/truth", indexes=idx,
                             columns=rr.Points3D.columns(positions=arrays[f"object_{name}"][:, :3]))
        history = runner.sensors.history if runner.sensors is not None else {}
        for name, rows in history.items():
            if rows:
                ts = np.array([t for t, _, _ in rows])
                pos = np.array([est[:3] for _, est, _ in rows])
                rec.send_columns(f"objects/{name}/estimate", indexes=[rr.TimeColumn(TIMELINE, duration=ts)],
                                 columns=rr.Points3D.columns(positions=pos))


def _body_name(m: mujoco.MjModel, b: int) -> str:
    return (m.body(b).name or f"body{b}").replace("/", "_")


def _log_geoms(rr: Any, rec: Any, path: str, m: mujoco.MjModel, geoms: list[int]) -> None:
    """A body's geoms as Rerun primitives in the body's frame (static)."""
    for g in geoms:
        kind, size, pos = int(m.geom_type[g]), m.geom_size[g], m.geom_pos[g]
        quat = m.geom_quat[g][[1, 2, 3, 0]]
        rgba = m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0 else m.geom_rgba[g]
        color = (np.clip(rgba, 0, 1) * 255).astype(np.uint8)
        name = f"{path}/{m.geom(g).name or f'geom{g}'}".replace(" ", "_")
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            item = rr.Boxes3D(half_sizes=[size], centers=[pos], quaternions=[quat], colors=[color], fill_mode="solid")
        elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            item = rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], centers=[pos], colors=[color], fill_mode="solid")
        elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            item = rr.Ellipsoids3D(half_sizes=[size], centers=[pos], quaternions=[quat], colors=[color],
                                   fill_mode="solid")
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:  # rerun's capsule starts at its origin and runs along +z
            start = pos - _matrix(m.geom_quat[g]) @ np.array([0.0, 0.0, size[1]])
            item = rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[start], quaternions=[quat],
                                 colors=[color])
        elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            item = rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[pos], quaternions=[quat],
                                  colors=[color], fill_mode="solid")
        elif kind == mujoco.mjtGeom.mjGEOM_MESH:
            mesh = int(m.geom_dataid[g])
            va, vn = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
            fa, fn = int(m.mesh_faceadr[mesh]), int(m.mesh_facenum[mesh])
            verts = m.mesh_vert[va : va + vn] @ _matrix(m.geom_quat[g]).T + pos
            item = rr.Mesh3D(vertex_positions=verts, triangle_indices=m.mesh_face[fa : fa + fn], albedo_factor=color)
        elif kind == mujoco.mjtGeom.mjGEOM_PLANE:
            half = [size[0] or 5.0, size[1] or 5.0, 0.0005]
            item = rr.Boxes3D(half_sizes=[half], centers=[pos], quaternions=[quat], colors=[[60, 80, 100, 255]],
                              fill_mode="solid")
        else:
            continue
        rec.log(name, item, static=True)


def _matrix(quat: np.ndarray) -> np.ndarray:
    out = np.empty(9)
    mujoco.mju_quat2Mat(out, quat)
    return out.reshape(3, 3)


__all__ = ["FORCE_SCALE", "TIMELINE", "RerunRecording"]
