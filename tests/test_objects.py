"""Objects declared as data in a task config (``scene.objects``): schema, symmetry, build, checks and the CLI."""

import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.geometry import geom_parts, support
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.placement import rest_height
from nextage_qp.manipulation.runner import Runner, build_robot
from nextage_qp.scene.build import _prism_mesh
from nextage_qp.scene.objects import ObjectDecl, PartDecl, standing_height, volume

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"
DOCK = ROOT / "configs" / "dock_dumbbell.yaml"
TABLE_TOP = 0.875  # scenes/table.xml: top face of the table [m]
DOWN = np.array([0.0, 0.0, -1.0])


def build(*overrides: str, path: Path = PUSH):
    """The config with ``--set``-style overrides, and the robot compiled from it."""
    cfg = load_config(path, list(overrides))
    return cfg, build_robot(cfg, str(path))


def replace_cube(decl: str) -> str:
    return f"scene.objects.cube={decl}"


def lowest(model: mujoco.MjModel, obj: str) -> float:
    """How far the object's colliding geoms reach below its origin (body frame, upright) [m]."""
    return max(support(part, DOWN) for part in geom_parts(model, obj))


def geoms_of(model: mujoco.MjModel, body: str) -> list[int]:
    bid = model.body(body).id
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] == bid]


# -- 1. yaw symmetry -------------------------------------------------------------------------------------------

SYMMETRIES = [
    ("{shape: box, size: [0.03, 0.03, 0.05]}", math.pi / 2),
    ("{shape: box, size: [0.03, 0.04, 0.03]}", math.pi),
    ("{shape: box, size: [0.0359, 0.0353, 0.12]}", math.pi / 2),  # sides 1.2 mm apart: no camera tells them apart
    ("{shape: box, size: [0.0359, 0.0347, 0.12]}", math.pi),
    ("{shape: prism, sides: 6, size: [0.03, 0.02]}", math.pi / 3),
    ("{shape: prism, sides: 3, size: [0.03, 0.02]}", 2 * math.pi / 3),
    ("{shape: prism, sides: 4, size: [0.03, 0.02]}", math.pi / 2),
    ("{shape: cylinder, size: [0.03, 0.035]}", 0.0),
    ("{shape: capsule, size: [0.02, 0.03]}", 0.0),
    ("{shape: sphere, size: [0.03]}", 0.0),
    ("{shape: compound, parts: [{shape: box, size: [0.03, 0.03, 0.02]}, "
     "{shape: sphere, size: [0.02], pos: [0, 0, 0.04]}]}", 2 * math.pi),
    ("{shape: compound, yaw_symmetry: 0.7, parts: [{shape: box, size: [0.03, 0.03, 0.02]}]}", 0.7),
    ("{shape: box, size: [0.03, 0.04, 0.03], yaw_symmetry: 0}", 0.0),
]


@pytest.mark.parametrize("decl,expected", SYMMETRIES)
def test_symmetry_follows_the_shape_and_reaches_the_compiled_robot(decl, expected):
    cfg, robot = build(replace_cube(decl))
    assert cfg.scene.objects["cube"].symmetry() == pytest.approx(expected, abs=1e-12)
    assert robot.yaw_symmetry("cube") == pytest.approx(expected, abs=1e-12)


# -- 2. validation ---------------------------------------------------------------------------------------------

BAD = [  # (id, override, what the one-line message must name)
    ("unknown shape", replace_cube("{shape: hexagon, size: [0.03, 0.035]}"), "scene.objects.cube.shape"),
    ("box with 2 sizes", replace_cube("{shape: box, size: [0.03, 0.035]}"), "scene.objects.cube: a box takes 3"),
    ("cylinder with 3 sizes", replace_cube("{shape: cylinder, size: [0.03, 0.035, 0.01]}"),
     "scene.objects.cube: a cylinder takes 2"),
    ("box without size", replace_cube("{shape: box}"), "scene.objects.cube: a box needs size"),
    ("zero size", replace_cube("{shape: box, size: [0.03, 0, 0.03]}"), "scene.objects.cube.size[1]"),
    ("negative size", replace_cube("{shape: sphere, size: [-0.03]}"), "scene.objects.cube.size[0]"),
    ("nan size", replace_cube("{shape: cylinder, size: [.nan, 0.03]}"), "scene.objects.cube.size[0]"),
    ("inf size", replace_cube("{shape: cylinder, size: [0.03, .inf]}"), "scene.objects.cube.size[1]"),
    ("sides without prism", replace_cube("{shape: box, size: [0.03, 0.03, 0.03], sides: 6}"),
     "scene.objects.cube: sides"),
    ("prism without sides", replace_cube("{shape: prism, size: [0.03, 0.03]}"), "scene.objects.cube: sides"),
    ("prism with 2 sides", replace_cube("{shape: prism, sides: 2, size: [0.03, 0.03]}"), "scene.objects.cube.sides"),
    ("compound without parts", replace_cube("{shape: compound}"), "scene.objects.cube: a compound takes parts"),
    ("parts on a box", replace_cube("{shape: box, size: [0.03, 0.03, 0.03], parts: [{shape: sphere, size: [0.01]}]}"),
     "scene.objects.cube: parts go with shape: compound"),
    ("bad part", replace_cube("{shape: compound, parts: [{shape: box, size: [0.01]}]}"), "scene.objects.cube.parts[0]"),
    ("fixed body name", "scene.objects.table={shape: sphere, size: [0.03]}", "scene.objects.table"),
    ("inside the table", "scene.poses.cube.pos=[0.33,0,0.89]", "object 'cube' starts 20.0 mm inside 'table'"),
    ("inside another object", "scene.objects.puck={shape: cylinder, size: [0.03, 0.02], pos: [0.34, 0.01]}",
     "object 'puck' starts"),
]
BAD_IDS = [case[0] for case in BAD]


@pytest.mark.parametrize("override,named", [case[1:] for case in BAD], ids=BAD_IDS)
def test_bad_declaration_is_a_config_error(override, named):
    with pytest.raises(ConfigError) as info:
        build(override)
    assert named in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("override,named", [case[1:] for case in BAD], ids=BAD_IDS)
def test_bad_declaration_exits_2_with_one_line_naming_the_key(capsys, override, named):
    assert main(["run", str(PUSH), "--set", override, "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert named in captured.err.splitlines()[-1]
    assert captured.out == ""


@pytest.mark.parametrize("override,named", [BAD[0][1:], BAD[-2][1:]], ids=[BAD[0][0], BAD[-2][0]])
def test_console_script_exits_2_with_the_key_on_the_last_line(override, named):
    script = Path(sys.executable).with_name("nextage-qp")
    proc = subprocess.run([str(script), "run", "configs/push_cube.yaml", "--set", override], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert named in proc.stderr.strip().splitlines()[-1]


def test_fixed_body_name_error_names_the_config_file():
    with pytest.raises(ConfigError) as info:
        build("scene.objects.table={shape: sphere, size: [0.03]}")
    assert str(info.value).startswith(f"{PUSH}: scene.objects.table:")


# -- 3. geometry after the build -------------------------------------------------------------------------------

SHAPES = [
    "{shape: box, size: [0.02, 0.04, 0.03], mass: 0.2}",
    "{shape: cylinder, size: [0.03, 0.035], mass: 0.2}",
    "{shape: capsule, size: [0.02, 0.03], mass: 0.2}",
    "{shape: sphere, size: [0.03], mass: 0.2}",
    "{shape: prism, sides: 6, size: [0.03, 0.02], mass: 0.2}",
    "{shape: prism, sides: 3, size: [0.03, 0.02], mass: 0.2}",
    "{shape: compound, mass: 0.2, parts: [{shape: box, size: [0.05, 0.01, 0.01], pos: [0, 0, 0.02]}, "
    "{shape: cylinder, size: [0.02, 0.03], pos: [0.04, 0, 0]}]}",
]


@pytest.mark.parametrize("decl", SHAPES, ids=["box", "cylinder", "capsule", "sphere", "prism6", "prism3", "compound"])
def test_replaced_cube_keeps_name_joint_and_mass_and_stands_on_the_table(decl):
    cfg, robot = build(replace_cube(decl))
    m = robot.model
    body = m.body("cube").id
    assert robot.object_names == ("cube",)
    joint = m.joint("cube_joint")
    assert joint.type[0] == mujoco.mjtJoint.mjJNT_FREE and joint.bodyid[0] == body
    assert m.body_mass[body] == pytest.approx(0.2)
    z = m.body_pos[body][2]
    assert z - TABLE_TOP == pytest.approx(standing_height(cfg.scene.objects["cube"]), abs=1e-6)
    assert z - lowest(m, "cube") == pytest.approx(TABLE_TOP, abs=1e-6)  # lowest point on the table top
    data = mujoco.MjData(m)
    mujoco.mj_forward(m, data)
    assert rest_height(robot, data, "cube") == pytest.approx(z, abs=1e-6)


def test_scene_masses_override_the_declared_mass():
    _, robot = build(replace_cube("{shape: cylinder, size: [0.03, 0.035], mass: 0.2}"), "scene.masses.cube=0.25")
    assert robot.model.body_mass[robot.model.body("cube").id] == pytest.approx(0.25)


def test_declared_friction_reaches_every_geom():
    _, robot = build(replace_cube("{shape: compound, friction: 1.5, parts: [{shape: box, size: [0.03, 0.03, 0.02]}, "
                                  "{shape: sphere, size: [0.02], pos: [0, 0, 0.03]}]}"))
    m = robot.model
    assert [float(m.geom_friction[g][0]) for g in geoms_of(m, "cube")] == [1.5, 1.5]


@pytest.mark.parametrize("sides", [3, 6, 8])
def test_prism_compiles_to_a_mesh_with_two_rings_of_vertices(sides):
    _, robot = build(replace_cube(f"{{shape: prism, sides: {sides}, size: [0.03, 0.02]}}"))
    m = robot.model
    (geom,) = geoms_of(m, "cube")
    assert m.geom_type[geom] == mujoco.mjtGeom.mjGEOM_MESH
    assert m.mesh_vertnum[m.geom_dataid[geom]] == 2 * sides


def test_cylinder_reaches_its_radius_in_every_horizontal_direction():
    _, robot = build(replace_cube("{shape: cylinder, size: [0.03, 0.035]}"))
    parts = geom_parts(robot.model, "cube")
    for angle in np.linspace(0.0, 2 * np.pi, 7):
        d = np.array([np.cos(angle), np.sin(angle), 0.0])
        assert max(support(p, d) for p in parts) == pytest.approx(0.03, abs=1e-12)
    assert max(support(p, -DOWN) for p in parts) == pytest.approx(0.035, abs=1e-12)


def test_yawed_box_extent_is_its_half_size_along_its_axes():
    cfg = load_config(PUSH, [replace_cube("{shape: box, size: [0.02, 0.04, 0.03]}"), "scene.poses.cube.yaw=0.4"])
    view = Runner(cfg, str(PUSH)).view
    rot = view.body_pose("cube").rot
    assert rot[:, 0] == pytest.approx([np.cos(0.4), np.sin(0.4), 0.0], abs=1e-9)
    for axis, half in enumerate((0.02, 0.04, 0.03)):
        assert view.extent("cube", rot[:, axis]) == pytest.approx(half, abs=1e-9)
        assert view.extent("cube", -rot[:, axis]) == pytest.approx(half, abs=1e-9)


@pytest.fixture(scope="module")
def dumbbell_runner():
    return Runner(load_config(DOCK), str(DOCK))


def test_dumbbell_compound_mass_and_inertia(dumbbell_runner):
    m = dumbbell_runner.robot.model
    body = m.body("dumbbell").id
    assert m.body_mass[body] == pytest.approx(0.3)
    assert m.body_inertia[body] == pytest.approx([0.01084329, 0.01084329, 0.00371606], abs=1e-8)
    assert m.body_ipos[body] == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    assert dumbbell_runner.robot.yaw_symmetry("dumbbell") == pytest.approx(math.pi / 2)


def test_dumbbell_table_pairs_are_repointed_to_the_new_parts(dumbbell_runner):
    m = dumbbell_runner.robot.model
    parts = set(geoms_of(m, "dumbbell"))
    table = m.geom("table_top").id
    pairs = [{int(m.pair_geom1[i]), int(m.pair_geom2[i])} for i in range(m.npair)]
    with_table = [p for p in pairs if table in p]
    assert len(parts) == 3 and len(with_table) == 3
    assert {g for p in with_table for g in p if g != table} == parts
    assert all(m.pair_friction[i][0] == 10.0 for i in range(m.npair))


def test_dumbbell_grip_geometry_is_the_top_plate(dumbbell_runner):
    view = dumbbell_runner.view
    for lateral in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]):
        height, half_width = view.grip_geometry("dumbbell", np.array(lateral))
        assert height == pytest.approx(0.105, abs=1e-9)
        assert half_width == pytest.approx(0.084, abs=1e-9)


@pytest.mark.parametrize("part", [
    "{shape: cylinder, size: [0.02, 0.05], axis: x}",
    "{shape: capsule, size: [0.02, 0.05], axis: y}",
    "{shape: prism, sides: 4, size: [0.03, 0.05], axis: y}",
    "{shape: prism, sides: 6, size: [0.03, 0.05], axis: x}",
    "{shape: prism, sides: 6, size: [0.03, 0.05], axis: y}",
    "{shape: prism, sides: 3, size: [0.03, 0.05], axis: y}",
    "{shape: box, size: [0.05, 0.02, 0.01], axis: x}",
])
def test_a_part_on_its_side_stands_on_the_table(part):
    cfg, robot = build(replace_cube(f"{{shape: compound, parts: [{part}]}}"))
    m = robot.model
    z = m.body_pos[m.body("cube").id][2]
    assert z - lowest(m, "cube") == pytest.approx(TABLE_TOP, abs=1e-6)
    assert lowest(m, "cube") == pytest.approx(standing_height(cfg.scene.objects["cube"]), abs=1e-6)


# -- 4. volume and standing height -----------------------------------------------------------------------------

R, H = 0.03, 0.02
VOLUMES = [
    (dict(shape="box", size=(0.02, 0.04, 0.03)), 0.04 * 0.08 * 0.06, 0.03),
    (dict(shape="cylinder", size=(R, H)), math.pi * R**2 * 2 * H, H),
    (dict(shape="capsule", size=(R, H)), math.pi * R**2 * 2 * H + 4 / 3 * math.pi * R**3, H + R),
    (dict(shape="sphere", size=(R,)), 4 / 3 * math.pi * R**3, R),
    (dict(shape="prism", sides=3, size=(R, H)), 3 * math.sqrt(3) / 4 * R**2 * 2 * H, H),
    (dict(shape="prism", sides=4, size=(R, H)), 2 * R**2 * 2 * H, H),  # a square of diagonal 2R
    (dict(shape="prism", sides=6, size=(R, H)), 3 * math.sqrt(3) / 2 * R**2 * 2 * H, H),
]


@pytest.mark.parametrize("kwargs,vol,height", VOLUMES, ids=[f"{k['shape']}{k.get('sides', '')}" for k, _, _ in VOLUMES])
def test_volume_and_standing_height_closed_forms(kwargs, vol, height):
    assert volume(PartDecl(**kwargs)) == pytest.approx(vol, rel=1e-12)
    assert standing_height(ObjectDecl(**kwargs)) == pytest.approx(height, rel=1e-12)


@pytest.mark.parametrize("sides", [3, 5, 6])
def test_prism_volume_matches_mujocos_mesh_volume(sides):
    part = PartDecl(shape="prism", sides=sides, size=(R, H))
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="probe")
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=_prism_mesh(spec, "p", part), density=1.0)
    assert spec.compile().body_mass[1] == pytest.approx(volume(part), rel=1e-5)


def test_compound_standing_height_counts_each_part_offset():
    decl = ObjectDecl(shape="compound", parts=(
        PartDecl(shape="box", size=(0.05, 0.02, 0.01), pos=(0.0, 0.0, 0.02)),  # bottom 0.01 above the origin
        PartDecl(shape="capsule", size=(0.01, 0.02), axis="y", pos=(0.0, 0.0, -0.01)),  # bottom 0.02 below
        PartDecl(shape="cylinder", size=(0.015, 0.01), pos=(0.0, 0.0, -0.005)),  # bottom 0.015 below
    ))
    assert standing_height(decl) == pytest.approx(0.02, rel=1e-12)


# -- 5. target markers -----------------------------------------------------------------------------------------

def test_new_object_gets_a_visual_marker_on_the_table():
    _, robot = build("scene.objects.puck={shape: cylinder, size: [0.03, 0.02], pos: [0.45, 0.2]}")
    m = robot.model
    assert robot.object_names == ("cube", "puck")
    assert m.body_pos[m.body("puck").id] == pytest.approx([0.45, 0.2, TABLE_TOP + 0.02], abs=1e-9)
    marker = m.body("puck_target").id
    geoms = geoms_of(m, "puck_target")
    assert m.body_jntnum[marker] == 0 and m.body_mass[marker] == 0.0
    assert geoms and all(m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0 for g in geoms)
    assert [int(m.geom_type[g]) for g in geoms] == [mujoco.mjtGeom.mjGEOM_CYLINDER]
    assert m.geom_size[geoms[0]][:2] == pytest.approx([0.03, 0.02])
    assert m.body_pos[marker][2] == pytest.approx(TABLE_TOP + 0.02, abs=1e-9)
    assert robot.yaw_symmetry("puck") == 0.0


def test_replaced_cube_marker_takes_the_new_shape_and_keeps_its_pad():
    _, robot = build(replace_cube("{shape: sphere, size: [0.03]}"))
    m = robot.model
    geoms = geoms_of(m, "cube_target")
    assert all(m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0 for g in geoms)
    kinds = sorted(int(m.geom_type[g]) for g in geoms)
    assert kinds == sorted([int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_SPHERE)])  # the flat pad, the ghost
    assert "cube_target_target" not in [m.body(b).name for b in range(m.nbody)]


def test_a_push_that_times_out_on_a_tipping_object_says_so():
    """A narrow box on a grippy table tips over its leading edge under the hand's face rather than slide: the push
    pauses while it is tilted, and a timeout spent mostly so names the tipping, not only the phase's counters."""
    from nextage_qp.api import run_task

    result = run_task(ROOT / "configs" / "push_cube.yaml", overrides=[
        "scene.objects.cube={shape: box, size: [0.037, 0.0165, 0.035]}", "scene.poses.cube.pos=[0.372,-0.024,0.91]",
        "scene.poses.cube.yaw=0.438", "scene.poses.cube_target.pos=[0.73,-0.049,0.91]", "scene.masses.cube=0.21",
        "scene.friction_scale.cube=1.8", "phases.0.timeout=20",
        "phases.0.height=0.008", "ik.collision_pairs.0.min_distance=0.008"])  # met 22 mm up, not 17: it tips
    assert not result.success
    assert "timed out after 20 s of simulated time: cube tipped under the tool for" in result.error, result.error
    assert result.phases[0]["tilt_pauses"] * 0.02 >= 0.25 * 20


def test_the_same_narrow_box_slides_when_the_hand_meets_it_low():
    """The box above, pushed with the config's own height: the hand meets it 17 mm up rather than 22, the wedge number
    mu * h / (2 w) drops from 1.2 to 0.93, and it slides to its target (tools/push_wedge.py)."""
    from nextage_qp.api import run_task

    result = run_task(ROOT / "configs" / "push_cube.yaml", overrides=[
        "scene.objects.cube={shape: box, size: [0.037, 0.0165, 0.035]}", "scene.poses.cube.pos=[0.372,-0.024,0.91]",
        "scene.poses.cube.yaw=0.438", "scene.poses.cube_target.pos=[0.73,-0.049,0.91]", "scene.masses.cube=0.21",
        "scene.friction_scale.cube=1.8"])
    assert result.success, result.error
    assert result.object_error_xy_m <= 0.005


def test_the_right_hand_takes_a_correction_at_the_push_height():
    """The push config's right hand may come as close to the table as the left, so a correction it reaches more
    squarely goes to it (push sweep, seed 0, episode 21: the first push leaves the cube off to the left hand's far side)."""
    from nextage_qp.api import run_task

    result = run_task(ROOT / "configs" / "push_cube.yaml", overrides=[
        "scene.poses.cube.pos=[0.3343208139417267,0.02275795790483376,0.91]", "scene.poses.cube.yaw=0.1658889769110009",
        "scene.poses.cube_target.pos=[0.7400927167260142,-0.03596129131127077,0.91]",
        "scene.masses.cube=0.08977215397834927", "scene.friction_scale.cube=1.9002615929157902", "seed=1343950750"])
    assert result.success, result.error
    assert result.phases[0].get("handovers", 0) >= 1
