"""A robot camera rendered offscreen: depth (with the sensor's noise), RGB, and what the robot's model expects to see.

:class:`RobotCamera` is the world side of perception: it renders the simulated world from a camera of the robot file
(markers and collision geoms hidden, no shadows or reflections, as software rendering wants). It also renders the
*expected background*: the robot's own model at its measured joints with the known static scene (table,
obstacles) and without the free objects, from the camera pose forward kinematics of the measured joints gives. The
estimator (:mod:`nextage_qp.sensing.camera.estimate`) gets the images, the intrinsics and that pose, nothing else.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from nextage_qp.errors import one_line
from nextage_qp.robots.cameras import CameraFile

SHOWN_GROUPS = (0, 2)
"""Geom groups a robot camera sees: scene geoms (0) and visual meshes (2); markers (1), collision geoms (3) and
debug sites (4+) are the simulator's, not the world's."""
MAX_RANGE = 3.0
"""Depth beyond this is no return [m]."""
PLANE_HALF = 1000.0
"""Half-size [m] of the finite plane a robot camera renders for an infinite one (:func:`finite_planes`)."""
HIDDEN_GROUP = 5
"""Geom group no robot camera shows (:data:`SHOWN_GROUPS`): where :meth:`RobotCamera.own` puts all but the robot."""
AWAY = -50.0
"""Height [m] the free objects are moved to in the expected-background model (out of every view)."""


PACKAGES = "Debian libegl1 libegl-mesa0 libgl1-mesa-dri (MUJOCO_GL=egl) or libosmesa6 (MUJOCO_GL=osmesa)"
"""What headless rendering needs on a machine without a display."""


def render_problem() -> str | None:
    """None if offscreen rendering works here, else one line saying why and which packages it needs."""
    try:
        r = mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 16, 16)
        r.close()
    except Exception as exc:
        return f"offscreen rendering unavailable ({one_line(exc)}); install {PACKAGES}"
    return None


FAST_CAMERA_FLAGS = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX)
"""Rendering a robot camera turns these off (software rendering)."""


def shown_option() -> mujoco.MjvOption:
    """What a robot camera sees: the :data:`SHOWN_GROUPS` of geoms, no sites."""
    opt = mujoco.MjvOption()
    opt.geomgroup[:] = 0
    for g in SHOWN_GROUPS:
        opt.geomgroup[g] = 1
    opt.sitegroup[:] = 0
    return opt


def finite_planes(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` for a robot camera: its infinite planes made :data:`PLANE_HALF` wide and one quad each.

    The renderer bakes each plane's grid of quads into its context: an infinite floor (50 mm grid) is drawn out to
    the far clipping plane in thousands of quads, half of a depth frame's time on a software renderer, and 60 % of an
    RGB frame's where the floor fills the view. A depth image does not see the grid: within :data:`MAX_RANGE` of a
    camera less than ``PLANE_HALF - MAX_RANGE`` from the plane's origin it is the same to a micrometre (float32
    rounding). An RGB image differs in the far floor's shading alone (0.8 % of a Nextage head camera's pixels by more
    than 10 of 255).
    """
    out = copy.copy(model)
    for i in np.flatnonzero(out.geom_type == mujoco.mjtGeom.mjGEOM_PLANE):
        if min(out.geom_size[i, 0], out.geom_size[i, 1]) <= 0:
            out.geom_size[i] = PLANE_HALF
    return out


def depth_only(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` for a depth renderer: no multisampling, one quad per box face.

    Multisampling smooths colour edges and a box's face subdivision shades it; neither changes a depth image (the
    same to float32 rounding), and a software renderer spends a third of a depth frame's time on them.
    """
    out = copy.copy(model)
    out.vis.quality.offsamples = 0
    out.vis.quality.numquads = 1
    return out


def render_camera(renderer: mujoco.Renderer, data: mujoco.MjData, cam_id: int, option: mujoco.MjvOption) -> np.ndarray:
    """The image of ``data`` a robot camera takes (``option``: :func:`shown_option`; the renderer's depth mode kept)."""
    _scene(renderer, data, cam_id, option)
    return renderer.render()


def _scene(renderer: mujoco.Renderer, data: mujoco.MjData, cam_id: int, option: mujoco.MjvOption) -> None:
    """Update the renderer's scene to what a robot camera sees of ``data``, with the :data:`FAST_CAMERA_FLAGS` off."""
    renderer.update_scene(data, camera=cam_id, scene_option=option)
    for flag in FAST_CAMERA_FLAGS:
        renderer.scene.flags[flag] = 0


def render_window(renderer: mujoco.Renderer, data: mujoco.MjData, cam_id: int, option: mujoco.MjvOption,
                  cut: tuple[int, int, int, int], K: np.ndarray) -> np.ndarray:
    """Rows ``r0:r1`` and columns ``c0:c1`` (``cut``) of the image :func:`render_camera` gives, rendered alone.

    The camera's frustum is narrowed to the window and drawn into a viewport of its size, so a software renderer
    fills and reads back only its pixels (a window of a sixth of a 640 x 480 head image: 2.4 ms against 10.3 ms for
    the whole RGB image); the pixels are those of the whole image's window (RGB within rasterisation rounding: at most
    10 of 255, on 2-7 % of them; depth to float32 rounding). The renderer's mode is kept: RGB, or depth [m] as
    :meth:`mujoco.Renderer.render` gives it. A renderer without its own GL context (a build whose internals differ)
    renders the whole image and cuts it.
    """
    r0, r1, c0, c1 = cut
    ctx, gl = getattr(renderer, "_mjr_context", None), getattr(renderer, "_gl_context", None)
    depth = bool(getattr(renderer, "_depth_rendering", False))
    if ctx is None or gl is None:
        return render_camera(renderer, data, cam_id, option)[r0:r1, c0:c1]
    _scene(renderer, data, cam_id, option)
    if depth:  # as Renderer.render draws depth: segment colours (exact far depth), no lighting
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
    for cam in renderer.scene.camera:  # both eyes of MuJoCo's stereo pair: the window on the near plane
        n = cam.frustum_near
        left, right = (c0 - K[0, 2]) / K[0, 0] * n, (c1 - K[0, 2]) / K[0, 0] * n
        cam.frustum_center, cam.frustum_width = (left + right) / 2, (right - left) / 2
        cam.frustum_bottom, cam.frustum_top = (K[1, 2] - r1) / K[1, 1] * n, (K[1, 2] - r0) / K[1, 1] * n
    rect = mujoco.MjrRect(0, 0, c1 - c0, r1 - r0)
    gl.make_current()
    mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, ctx)
    mujoco.mjr_render(rect, renderer.scene, ctx)
    if not depth:
        out = np.empty((r1 - r0, c1 - c0, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(out, None, rect, ctx)
        return np.flipud(out)  # OpenGL's rows run bottom up
    buf = np.empty((r1 - r0, c1 - c0), dtype=np.float32)
    mujoco.mjr_readPixels(None, buf, rect, ctx)
    return np.flipud(_metric_depth(buf, renderer.model))


def _returns(depth: np.ndarray) -> np.ndarray:
    """A rendered depth image [m] as the sensor gives it: NaN (no return) at and beyond ``MAX_RANGE``."""
    return np.where(depth < MAX_RANGE, depth, np.nan).astype(np.float32)


def _metric_depth(buf: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """Depth [m] from a perspective camera's reversed-Z depth buffer, as :meth:`mujoco.Renderer.render` converts it."""
    extent = model.stat.extent
    znear, zfar = np.float32(model.vis.map.znear * extent), np.float32(model.vis.map.zfar * extent)
    c_coef = -(zfar + znear) / (zfar - znear)
    d_coef = -(np.float32(2) * zfar * znear) / (zfar - znear)
    c_coef = np.float32(-0.5) * c_coef - np.float32(0.5)
    d_coef = np.float32(-0.5) * d_coef
    return (d_coef / (buf.astype(np.float64) + c_coef)).astype(np.float32)


class RobotCamera:
    """Renders one camera of the robot (see the module docstring).

    Args:
        model: The compiled task scene with the robot and its cameras.
        name: The camera's name.
        spec: The camera's robot-file entry.
        robot: The :class:`~nextage_qp.robots.model.Robot` (joint addresses, free objects).
        seed: Seed of the depth noise.
    """

    def __init__(self, model: mujoco.MjModel, name: str, spec: CameraFile, robot, seed: int) -> None:
        self.model, self.name, self.spec, self.robot = model, name, spec, robot
        self.cam_id = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name))
        self.K = spec.intrinsics
        self.finite = finite_planes(model)
        self.renderer = mujoco.Renderer(depth_only(self.finite), spec.height, spec.width)
        self.renderer.enable_depth_rendering()
        self._rgb: mujoco.Renderer | None = None  # made on the first RGB image
        self._own: mujoco.Renderer | None = None  # the robot alone, made on the first :meth:`own`
        self.option = shown_option()
        self.rng = np.random.default_rng(seed)
        self.kin = mujoco.MjData(model)  # the robot's own model at its measured joints, objects away
        for obj in robot.object_names:
            s = robot.object_qpos_slice(obj)
            self.kin.qpos[s.start + 2] = AWAY

    def _render(self, data: mujoco.MjData, depth: bool, cut: tuple[int, int, int, int] | None = None,
                noisy: bool = False) -> np.ndarray:
        """The image of ``data``: RGB, or depth [m] whole or in the window ``cut`` (NaN elsewhere).

        Depth is NaN where there is no return; ``noisy``: with the sensor's noise, drawn for the rendered pixels alone.
        """
        if not depth:
            return render_camera(self._rgb_renderer(), data, self.cam_id, self.option)
        add = self.noisy if noisy else (lambda z: z)
        if cut is None:
            return add(_returns(render_camera(self.renderer, data, self.cam_id, self.option)))
        r0, r1, c0, c1 = cut
        full = np.full((self.spec.height, self.spec.width), np.nan, dtype=np.float32)
        full[r0:r1, c0:c1] = add(_returns(render_window(self.renderer, data, self.cam_id, self.option, cut, self.K)))
        return full

    def _rgb_renderer(self) -> mujoco.Renderer:
        """The RGB renderer, made on the first RGB image."""
        if self._rgb is None:
            self._rgb = mujoco.Renderer(self.finite, self.spec.height, self.spec.width)
        return self._rgb

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The camera's pose (position [m], 3x3 rotation) from forward kinematics of the measured joints ``q``."""
        self.robot.set_q(self.kin, q)
        mujoco.mj_kinematics(self.model, self.kin)
        mujoco.mj_camlight(self.model, self.kin)
        return self.kin.cam_xpos[self.cam_id].copy(), self.kin.cam_xmat[self.cam_id].reshape(3, 3).copy()

    def own(self) -> np.ndarray:
        """Depth [m] of the robot's own model alone at the pose of the last :meth:`pose` (NaN: no robot there).

        What a self-filter compares the measured depth with (:func:`.occupancy.self_filter`); its
        renderer is made on the first call.
        """
        if self._own is None:
            from nextage_qp.robots.model import robot_bodies

            model = depth_only(self.finite)
            mine = np.isin(model.geom_bodyid, list(robot_bodies(self.robot)))
            model.geom_group[~mine] = HIDDEN_GROUP  # everything but the robot out of every view
            renderer = mujoco.Renderer(model, self.spec.height, self.spec.width)
            renderer.enable_depth_rendering()
            self._own = renderer
        return _returns(render_camera(self._own, self.kin, self.cam_id, self.option))

    def expected(self, cut: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Depth [m] the model expects at the pose of the last :meth:`pose`: the robot and the static scene only.

        With ``cut``: rendered in rows ``r0:r1`` and columns ``c0:c1`` alone, NaN elsewhere (:func:`render_window`).
        """
        return self._render(self.kin, depth=True, cut=cut)

    def depth(self, data: mujoco.MjData, cut: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """The sensor's depth image [m] of the world ``data`` (NaN: no return), with its noise model.

        With ``cut``: rendered in rows ``r0:r1`` and columns ``c0:c1`` alone, NaN elsewhere (:func:`render_window`).
        """
        return self._render(data, depth=True, cut=cut, noisy=True)

    def noisy(self, z: np.ndarray) -> np.ndarray:
        """``z`` with axial noise growing with the distance squared and missing pixels at depth edges."""
        n = self.spec.depth_noise
        if n.sigma_m == 0 and n.per_m2 == 0 and n.edge_dropout == 0:
            return z
        out = z + self.rng.standard_normal(z.shape).astype(np.float32) * (n.sigma_m + n.per_m2 * z * z)
        if n.edge_dropout > 0:
            step = np.zeros(z.shape, dtype=bool)
            with np.errstate(invalid="ignore"):
                dy, dx = np.abs(np.diff(z, axis=0)) > n.edge_m, np.abs(np.diff(z, axis=1)) > n.edge_m
            step[1:] |= dy
            step[:-1] |= dy
            step[:, 1:] |= dx
            step[:, :-1] |= dx
            out[step & (self.rng.random(z.shape) < n.edge_dropout)] = np.nan
        return out

    def rgb(self, data: mujoco.MjData, cut: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """The camera's RGB image (H, W, 3) uint8 of the world ``data``.

        With ``cut``: only its rows ``r0:r1`` and columns ``c0:c1`` (:func:`render_window`).
        """
        if cut is None:
            return self._render(data, depth=False)
        return render_window(self._rgb_renderer(), data, self.cam_id, self.option, cut, self.K)

    def close(self) -> None:
        """Free the renderers' GL contexts."""
        self.renderer.close()
        for extra in (self._rgb, self._own):
            if extra is not None:
                extra.close()
