"""The sensors of a task config, the shoves, and their logs.

``perception.source`` and the ``faults`` block make a :class:`~nextage_qp.sensing.faulty.FaultySensors` (and its
camera).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco

from nextage_qp.errors import ConfigError
from nextage_qp.io.outputs import folder_problem
from nextage_qp.sensing.faults import FaultsConfig
from nextage_qp.sensing.faulty import FaultySensors
from nextage_qp.sensing.shoves import Shoves


def source_of(cfg: Any) -> str:
    """Where the config's object poses come from: ``perception.source``, else simulated or truth.

    Simulated when the config has ``faults.object_pose``.
    """
    simulated = cfg.faults is not None and cfg.faults.object_pose is not None
    return cfg.perception.source or ("simulated" if simulated else "truth")


def perception_of(cfg: Any, robot: Any, source: str) -> tuple[FaultySensors | None, Shoves | None]:
    """The faulty sensors and the shoves of a manipulation config (None, None with perfect sensors).

    A camera source gets its :class:`~nextage_qp.sensing.camera.source.CameraMeasurer` from :func:`attach_camera` once
    the simulation exists.

    Raises:
        ConfigError: A shove names a phase the config does not have, or a sensor the scene does not have;
            ``perception.source: simulated`` without ``faults.object_pose``; a ``perception.dump`` that cannot be
            written; ``perception.scan`` without a camera map to scan for or a head to look with.
    """
    where, faults = source_of(cfg), cfg.faults
    check_dump(cfg.perception.dump, where, source)
    if cfg.perception.obstacles == "camera" and (where != "camera" or cfg.perception.depth != "rendered"):
        raise ConfigError(f"{source}: perception.obstacles: camera maps the obstacles from rendered depth frames, "
                          f"but the poses come from {where}" + (" with stereo depth" if where == "camera" else "")
                          + "; set perception.source: camera and perception.depth: rendered, or perception.obstacles: "
                          "declared")
    p = cfg.perception
    if p.scan and not (where == "camera" and (p.map or p.obstacles == "camera") and p.look_at):
        raise ConfigError(f"{source}: perception.scan: the head looks over the work region for the camera's map; it "
                          "needs perception.source: camera, perception.map: true (or obstacles: camera) and "
                          "perception.look_at: true; set those, or perception.scan: false")
    if where == "simulated" and (faults is None or faults.object_pose is None):
        raise ConfigError(f"{source}: perception.source: simulated needs faults.object_pose (the simulated camera's "
                          f"rate, latency, noise, dropout); valid sources without it: truth, camera")
    if where != "simulated" and faults is not None and faults.object_pose is not None:
        faults = faults.model_copy(update={"object_pose": None})
    if faults is None and where != "camera":
        return None, None
    faults = faults or FaultsConfig()
    phases = {cfg.phase_name(i) for i in range(len(cfg.phases))} | {p.kind for p in cfg.phases}
    for i, s in enumerate(faults.shoves):
        if s.phase is not None and s.phase not in phases:
            raise ConfigError(f"{source}: faults.shoves[{i}].phase: {s.phase!r} is not a phase of this config; "
                              f"valid: {', '.join(sorted(phases))}")
    sites = [robot.model.site(int(robot.model.sensor_objid[k])).name for k in range(robot.model.nsensor)
             if int(robot.model.sensor_type[k]) == int(mujoco.mjtSensor.mjSENS_FORCE)]
    symmetry = {name: robot.yaw_symmetry(name) for name in robot.object_names}
    sensors = FaultySensors(faults, cfg.estimation, cfg.seed, sites, source, symmetry)
    bodies = {name: robot.model.body(name).id for name in robot.object_names}
    return sensors, Shoves(faults.shoves, bodies, cfg.timing.ctrl_dt)


def check_dump(dump: str | None, where: str, source: str) -> None:
    """Refuse a ``perception.dump`` that would never be written.

    Without a robot camera there is no frame to write; a folder that cannot take files is found before anything
    moves, not when the frame comes.

    Raises:
        ConfigError: Names the key, the value and what would be valid.
    """
    if dump is None:
        return
    if where != "camera":
        raise ConfigError(f"{source}: perception.dump: {dump!r} writes a frame of the robot's camera, but the poses "
                          f"come from {where}; set perception.source: camera or drop perception.dump")
    problem = folder_problem(Path(dump))
    if problem is not None:
        raise ConfigError(f"{source}: perception.dump: {dump!r}: {problem}; give a folder that can be written")


def attach_camera(cfg: Any, sensors: FaultySensors, robot: Any, data: mujoco.MjData, source: str,
                  places: Sequence[tuple[tuple[float, float], tuple[float, float]]] = ()) -> None:
    """Give ``sensors`` the robot camera of ``cfg.perception`` rendering the world ``data`` (camera source only).

    ``places``: rectangles of the table [m] the task puts objects in, which its obstacle map covers too.
    """
    if source_of(cfg) != "camera":
        return
    from nextage_qp.sensing.camera.source import CameraMeasurer

    def joints(t: float) -> Any:  # the measured joints (the same draw the PD law and the phases get at t)
        return sensors.joints(t, robot.get_q(data), robot.get_qd(data))[0]

    pc = cfg.perception
    measurer = CameraMeasurer(pc, robot, data, joints, cfg.seed, source, places)
    sensors.use_camera(measurer, measurer.noise_pos, pc.noise_rot_rad)


def log_estimates(sensors: FaultySensors, recorder: Any) -> None:
    """Add each object's estimate (every tick) and raw measurements (on arrival) to a run's log.

    Arrays ``extra_estimate_<object>`` and ``extra_measurement_<object>`` (k, 6): x, y, z [m], roll, pitch,
    yaw [rad], with their times in ``..._t``.
    """
    for name, rows in sensors.history.items():
        for t, est, raw in rows:
            recorder.add(f"estimate_{name}", t, est)
            if raw is not None:
                recorder.add(f"measurement_{name}", t, raw)
