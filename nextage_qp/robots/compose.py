"""A robot's model as a spec, and a task scene composed around it with MjSpec.

:func:`robot_spec` reads the robot file's model (MJCF, or URDF through :mod:`nextage_qp.robots.urdf`) and adds what
the file says the model lacks: the angle unit, frames as sites, excluded contacts, and an actuator for every joint
without one. :func:`compose` attaches that robot to a task scene (table, objects, targets, obstacles, lights: no
robot), at the robot file's mount, so the same scene file serves every robot.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.mobile.build import add_base, add_base_actuators
from nextage_qp.robots.cameras import add_cameras
from nextage_qp.robots.description import RobotDescription
from nextage_qp.scene.build import declare_objects, rest_on_table, table_top
from nextage_qp.scene.clutter import add_clutter
from nextage_qp.scene.compile import quiet_prefix_warning
from nextage_qp.scene.files import SceneOverrides, apply_overrides, load_scene
from nextage_qp.scene.seen_obstacles import add_pool

_ASSETS = ("meshes", "textures", "materials", "hfields", "skins")


def robot_spec(desc: RobotDescription) -> mujoco.MjSpec:
    """The robot's model as a spec, with the robot file's additions (not compiled).

    Raises:
        ConfigError: The model cannot be read, or the file names a body, joint or limit the model lacks.
    """
    if desc.model.suffix.lower() == ".urdf":
        from nextage_qp.robots.urdf import urdf_spec

        spec = urdf_spec(desc.model, desc.package_paths, desc.source)
    else:
        try:
            spec = mujoco.MjSpec.from_file(str(desc.model))
        except ValueError as exc:
            raise ConfigError(f"{desc.source}: model {desc.model}: {one_line(exc)}") from None
    if desc.angle is not None:
        spec.compiler.degree = desc.angle == "degree"
    bodies = {b.name for b in spec.bodies if b.name}
    for name, frame in desc.frames.items():
        if frame.body not in bodies:
            raise ConfigError(
                f"{desc.source}: frames.{name}.body: {frame.body!r} is not a body of the model; "
                f"bodies: {', '.join(sorted(bodies))}"
            )
        if spec.site(name) is not None:
            raise ConfigError(f"{desc.source}: frames.{name}: the model has a site {name!r} already; use it, or "
                              "give the frame another name")
        spec.body(frame.body).add_site(name=name, pos=list(frame.pos), quat=list(frame.quat))
    for i, pair in enumerate(desc.exclude):
        for name in pair:
            if name not in bodies:
                raise ConfigError(f"{desc.source}: exclude[{i}]: {name!r} is not a body of the model")
        spec.add_exclude(bodyname1=pair[0], bodyname2=pair[1])
    _add_missing_actuators(spec, desc)
    add_cameras(spec, dict(desc.cameras), desc.source)
    _add_wrench_sensors(spec, desc)
    return spec


def _add_wrench_sensors(spec: mujoco.MjSpec, desc: RobotDescription) -> None:
    """A force and a torque sensor (``SITE_force``, ``SITE_torque``) at each site of ``wrench_sensors``.

    MuJoCo's sensors read what the site's body and its parent exert on each other
    (:class:`~nextage_qp.sensing.sensors.WrenchSensor` turns that into the contact wrench).
    """
    sites = sorted(s.name for s in spec.sites if s.name)
    sensors = {s.name for s in spec.sensors if s.name}
    for i, site in enumerate(desc.wrench_sensors):
        if spec.site(site) is None:
            raise ConfigError(f"{desc.source}: wrench_sensors[{i}]: {site!r} is not a site of the model or a frame "
                              f"of the file; sites: {', '.join(sites) or 'none'}")
        for kind, sensor in (("force", mujoco.mjtSensor.mjSENS_FORCE), ("torque", mujoco.mjtSensor.mjSENS_TORQUE)):
            name = f"{site}_{kind}"
            if name in sensors:
                raise ConfigError(f"{desc.source}: wrench_sensors[{i}]: the model has a sensor {name!r} already")
            spec.add_sensor(name=name, type=sensor, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site)


def _add_missing_actuators(spec: mujoco.MjSpec, desc: RobotDescription) -> None:
    """A motor (gear 1, control = torque) for every robot joint no actuator drives.

    Its limit: the robot file's ``torque_limits``, else the joint's actuator-force range (a URDF's effort limit).
    """
    driven = {a.target for a in spec.actuators if a.trntype == mujoco.mjtTrn.mjTRN_JOINT}
    joints = {j.name: j for j in spec.joints}
    order = {j.name: i for i, j in enumerate(spec.joints)}
    for joint in sorted(desc.joints, key=lambda name: order.get(name, -1)):  # model order: contiguous actuators
        if joint not in joints:
            raise ConfigError(
                f"{desc.source}: {desc.where(joint)}: joint {joint!r} is not in the model; joints: "
                f"{', '.join(sorted(j for j in joints if j))}"
            )
        if joint in driven:
            continue
        limit = _per_joint(desc.torque_limits, joint)
        frc = joints[joint].actfrcrange  # a URDF's <limit effort=..> lands here
        if limit is None and joints[joint].actfrclimited != mujoco.mjtLimited.mjLIMITED_FALSE and np.ptp(frc) > 0:
            limit = float(np.max(np.abs(frc)))
        if limit is None:
            raise ConfigError(
                f"{desc.source}: joint {joint!r} has no actuator and no torque limit; give "
                f"torque_limits (N m, one value or per joint) in the robot file"
            )
        spec.add_actuator(
            name=joint, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT, ctrlrange=[-limit, limit], ctrllimited=1
        )


def _per_joint(value: float | Mapping[str, float] | None, joint: str) -> float | None:
    if value is None or isinstance(value, float | int):
        return None if value is None else float(value)
    return float(value[joint]) if joint in value else None


def compose(desc: RobotDescription, scene: str | Path, overrides: SceneOverrides | None = None) -> mujoco.MjSpec:
    """The task scene with the robot attached at its mount, the overrides applied (not compiled).

    The scene's options (time step, integrator, friction cone) and visual settings win; the robot model's own world
    geoms, lights and cameras (a demo floor, say) are left out, its assets whose names the scene uses too are
    renamed ``ROBOT/NAME``, and a free joint of its root (a humanoid's floating pelvis) is removed: the robot stands
    fixed at its mount (or on its wheeled base).

    Raises:
        ConfigError: The scene or the robot cannot be read, or an override names a body the scene lacks.
    """
    parent = load_scene(scene)
    child = robot_spec(desc)
    for element in [*child.worldbody.geoms, *child.worldbody.lights, *child.worldbody.cameras, *child.worldbody.sites]:
        child.delete(element)
    _rename_clashing_assets(child, parent, desc.name)
    _fix_floating_root(child)
    yaw = desc.mount.yaw
    robot_bodies = [b.name for b in child.bodies if b.name and b.name != "world"]
    if desc.base is not None:  # the robot stands on a wheeled base (nextage_qp.mobile.build)
        _, frame = add_base(parent, desc.base, desc.mount.pos, yaw)
    else:
        frame = parent.worldbody.add_frame(pos=list(desc.mount.pos),
                                           quat=[np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    with quiet_prefix_warning():  # an empty prefix: the robot keeps its own names
        try:
            parent.attach(child, frame=frame, prefix="")
        except ValueError as exc:  # e.g. a keyframe whose qpos does not fit the model
            raise ConfigError(f"{desc.source}: {desc.model.name} cannot be placed in {scene}: "
                              f"{str(exc).removeprefix('Error: ').splitlines()[0]}") from None
    if desc.base is not None:
        add_base_actuators(parent, desc.base)
        for name in robot_bodies:  # the base carries the robot: its own feet no longer stand on the floor
            parent.add_exclude(bodyname1="world", bodyname2=name)
    overrides = overrides or SceneOverrides()
    markers = declare_objects(parent, overrides.objects, str(scene)) if overrides.objects else []
    apply_overrides(parent, overrides, str(scene))
    if overrides.objects:
        rest_on_table(parent, overrides.objects, markers)
    if overrides.clutter is not None and overrides.clutter.count:
        top = table_top(parent)
        if top is None:
            raise ConfigError(f"{scene}: scene.clutter needs a table (a body named 'table' with a box on top)")
        fixed = [n for n, decl in overrides.objects.items() if decl.fixed]  # kept clear of, like the objects
        add_clutter(parent, overrides.clutter, top, str(scene), avoid=overrides.clutter_avoid, keep_clear=fixed,
                    placed_later=overrides.placed_later)
    if overrides.seen_pool:
        add_pool(parent)
    if overrides.speckle:
        from nextage_qp.scene.texture import speckle

        speckle(parent, robot_bodies)
    return parent


def _fix_floating_root(spec: mujoco.MjSpec) -> None:
    """Remove the free joints of a model's roots (a humanoid's floating pelvis), keeping their children's contacts off.

    A body welded to the world collides with its children (MuJoCo filters parent-child contacts except with the
    world): the pelvis would lock the torso's joint. Each body now welded to the world is excluded from its jointed
    children, as the free joint had them.
    """
    for joint in [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]:
        welded = [joint.parent]
        spec.delete(joint)
        while welded:
            body = welded.pop()
            for kid in body.bodies:
                if not kid.joints:
                    welded.append(kid)  # welded to it: to the world too
                elif body.name and kid.name:
                    spec.add_exclude(bodyname1=body.name, bodyname2=kid.name)


def _rename_clashing_assets(child: mujoco.MjSpec, parent: mujoco.MjSpec, robot: str) -> None:
    """Rename the child's assets whose names the parent also uses, and every reference to them."""
    taken = {a.name for kind in _ASSETS for a in getattr(parent, kind)}
    renamed: dict[str, str] = {}
    for kind in _ASSETS:
        for asset in getattr(child, kind):
            if asset.name and asset.name in taken:  # an unnamed asset is referred to by no name
                new = f"{robot}/{asset.name}"
                renamed[asset.name] = new
                asset.name = new
    if not renamed:
        return
    for geom in child.geoms:
        geom.material = renamed.get(geom.material, geom.material)
        geom.meshname = renamed.get(geom.meshname, geom.meshname)
    for material in child.materials:
        material.textures = [renamed.get(t, t) for t in material.textures]
