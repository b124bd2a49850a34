"""MoveIt planning scenes and motion-plan requests: parsing, pose conventions (xyzw -> wxyz,
object pose composed with primitive poses), joint matching by name, and every bad input of issue 19
(typed error; through the CLI one line and exit 2)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main
from splatplan.errors import PlanningError, SceneFormatError
from splatplan.scenes.moveit import load_moveit_request, load_moveit_scene, moveit_scene_from_dict
from splatplan.scenes.builtin.primitives import AnalyticScene, box_sdf, cylinder_sdf, make_box, make_cylinder, make_sphere, sphere_sdf

REPO = Path(__file__).resolve().parents[2]
MBM = REPO / ".." / "shared" / "data" / "mbm"
needs_mbm = pytest.mark.skipif(not (MBM / "problems").is_dir(), reason=f"{MBM} not present")

SCENE = textwrap.dedent(
    """
    world:
      collision_objects:
        - id: Can1
          primitives: [{type: cylinder, dimensions: [0.12, 0.03]}]
          primitive_poses: [{position: [0.5, 0.1, 0.3], orientation: [0, 0, 0.3826834, 0.9238795]}]
        - id: shelf
          pose: {position: {x: 1.0, y: 0.0, z: 0.0}, orientation: {x: 0, y: 0, z: 0.7071068, w: 0.7071068}}
          primitives:
            - {type: box, dimensions: [0.4, 0.2, 0.02]}
            - {type: sphere, dimensions: [0.05]}
          primitive_poses:
            - {position: [0.1, 0.0, 0.5], orientation: [0, 0, 0, 1]}
            - {position: [0.0, 0.2, 0.0], orientation: [0, 0, 0, 1]}
    """
)


class _Robot:
    """The parts of a Robot the request reader uses (two dofs, one fixed finger joint)."""

    name = "toy"
    joint_names = ["j1", "j2"]
    joint_limits = np.array([[-1.0, 1.0], [-2.0, 0.5]])

    class kin:  # noqa: N801 - mimics Robot.kin
        joint_names = ["", "j1", "j2", "finger"]


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def test_scene_poses_and_kinds(tmp_path):
    sc = load_moveit_scene(_write(tmp_path, "s.yaml", SCENE))
    assert sc.labels == ["shelf#0", "Can1", "shelf#1"] and sc.kinds == ["box", "cylinder", "sphere"]
    # cylinder: [height, radius], axis along z, orientation xyzw -> wxyz (45 deg about z)
    np.testing.assert_allclose(sc.cylinders[0, :5], [0.5, 0.1, 0.3, 0.03, 0.06])
    np.testing.assert_allclose(sc.cylinders[0, 5:], [0.9238795, 0, 0, 0.3826834], atol=1e-7)
    # object pose (90 deg about z at x = 1) composed with the primitive poses
    np.testing.assert_allclose(sc.boxes[0, :3], [1.0, 0.1, 0.5], atol=1e-6)
    np.testing.assert_allclose(sc.boxes[0, 3:6], [0.2, 0.1, 0.01])
    np.testing.assert_allclose(sc.spheres[0], [0.8, 0.0, 0.0, 0.05], atol=1e-6)
    # the box's long side now runs along world y
    assert sc.sdf(np.array([[1.0, 0.29, 0.5]]))[0] < 0 and sc.sdf(np.array([[1.19, 0.1, 0.5]]))[0] > 0
    p = np.random.default_rng(0).uniform(-0.5, 1.5, (500, 3))
    ref = np.min([box_sdf(p, sc.boxes[0]), cylinder_sdf(p, sc.cylinders[0]), sphere_sdf(p, sc.spheres[0])], axis=0)
    np.testing.assert_allclose(sc.sdf(p), ref, atol=1e-12)


def test_request_matching(tmp_path):
    req = _write(tmp_path, "r.yaml", """
        start_state: {joint_state: {name: [j2, j1, finger], position: [0.1, 0.2, 0.04]}}
        goal_constraints:
          - joint_constraints: [{joint_name: j2, position: -1.5}, {joint_name: j1, position: 0.9}]
        """)  # fmt: skip
    q0, q1 = load_moveit_request(req, _Robot)
    np.testing.assert_allclose(q0, [0.2, 0.1])  # matched by name; the fixed finger ignored
    np.testing.assert_allclose(q1, [0.9, -1.5])


BAD_REQUESTS = {
    "unknown joint in goal": ("goal_constraints: [{joint_constraints: [{joint_name: j1, position: 0}, {joint_name: j2, position: 0}, {joint_name: elbow9, position: 0}]}]", PlanningError, "elbow9"),
    "unknown joint in start": ("goal_constraints: [{joint_constraints: [{joint_name: j1, position: 0}, {joint_name: j2, position: 0}]}]", PlanningError, "wrist"),
    "goal above limit": ("goal_constraints: [{joint_constraints: [{joint_name: j1, position: 0}, {joint_name: j2, position: 0.75}]}]", PlanningError, "j2 = 0.75, 0.25 above its upper limit 0.5"),
    "goal below limit": ("goal_constraints: [{joint_constraints: [{joint_name: j1, position: -1.1}, {joint_name: j2, position: 0}]}]", PlanningError, "0.1 below its lower limit -1"),
    "missing goal joint": ("goal_constraints: [{joint_constraints: [{joint_name: j1, position: 0}]}]", PlanningError, "no value for joint(s) j2"),
    "no goal": ("planner_id: x", SceneFormatError, "goal_constraints"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD_REQUESTS))
def test_bad_requests(tmp_path, case):
    goal, exc, msg = BAD_REQUESTS[case]
    names = "[j1, j2, wrist]" if "start" in case else "[j1, j2]"
    text = f"start_state: {{joint_state: {{name: {names}, position: {[0.0] * (3 if 'start' in case else 2)}}}}}\n{goal}\n"
    with pytest.raises(exc, match=None) as err:
        load_moveit_request(_write(tmp_path, "r.yaml", text), _Robot)
    assert msg in str(err.value)


BAD_SCENES = {
    "unparsable": ("world: {collision_objects: [", "not valid YAML"),
    "mesh object": ("world: {collision_objects: [{id: mug, meshes: [{triangles: []}], mesh_poses: [{}]}]}", "'mug' is a mesh"),
    "unknown primitive": ("world: {collision_objects: [{id: funnel, primitives: [{type: cone, dimensions: [1, 1]}], primitive_poses: [{}]}]}", "'funnel': unknown primitive type 'cone'"),
    "no objects": ("world: {collision_objects: []}", "no collision objects"),
    "bad dimensions": ("world: {collision_objects: [{id: c, primitives: [{type: cylinder, dimensions: [1]}], primitive_poses: [{}]}]}", "needs 2 positive dimensions"),
    "not a scene": ("start_state: {}", "not a MoveIt planning scene"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scenes_cli_one_line_exit_2(tmp_path, capsys, case):
    text, msg = BAD_SCENES[case]
    path = _write(tmp_path, "s.yaml", text)
    with pytest.raises(SceneFormatError):
        load_moveit_scene(path)
    rc = main(["scene", "from-moveit", str(path), "--out", str(tmp_path / "x.ply")])
    err = capsys.readouterr().err
    assert rc == 2 and msg in err and err.count("\n") == 1 and err.startswith("splatplan: error:")
    assert not (tmp_path / "x.ply").exists()


def test_from_moveit_cli_writes_splats_and_exact_gt(tmp_path, capsys):
    path = _write(tmp_path, "s.yaml", SCENE)
    rc = main(["scene", "from-moveit", str(path), "--out", str(tmp_path / "x.ply"), "--n-splats", "5000", "--seed", "3"])
    assert rc == 0, capsys.readouterr().err
    gt = AnalyticScene.load(tmp_path / "x.gt.json")
    assert gt.kinds == ["box", "cylinder", "sphere"] and gt.meta["n_splats"] == 5000
    from splatplan.scenes.load import load_scene

    s = load_scene(tmp_path / "x.ply", filter_floaters=False)
    assert len(s) == 5000
    assert np.median(np.abs(gt.sdf(s.means.astype(np.float64)))) < gt.meta["base_spacing"]


def test_request_for_real_robot_and_scene_kinds():
    """Every primitive kind and the MBM cylinder convention, on an in-memory dict."""
    sc = moveit_scene_from_dict({"world": {"collision_objects": [{"id": "a", "primitives": [{"type": 3, "dimensions": [0.2, 0.05]}], "primitive_poses": [{"position": [0, 0, 0], "orientation": [0, 0, 0, 1]}]}]}})
    np.testing.assert_allclose(sc.cylinders[0, 3:5], [0.05, 0.1])  # numeric type 3 = cylinder


@needs_mbm
def test_mbm_files_load():
    from splatplan.robots import load_robot

    robot = load_robot(MBM / "panda" / "panda.urdf")  # (the spherized one takes ~12 s to load)
    for fam in ("table_pick", "box", "bookshelf_small"):
        d = MBM / "problems" / f"{fam}_panda"
        sc = load_moveit_scene(d / "scene0001.yaml")
        assert len(sc) >= 5
        q0, q1 = load_moveit_request(d / "request0001.yaml", robot)
        assert q0.shape == q1.shape == (7,)
    assert "cylinder" in load_moveit_scene(MBM / "problems" / "table_pick_panda" / "scene0001.yaml").kinds


def test_from_moveit_cli_spacing_is_a_count_per_area(tmp_path, capsys):
    """--spacing M samples at about M (a count per surface area); with --n-splats, or a spacing that
    gives too few or too many splats, it is one line and exit 2, and nothing is written."""
    from splatplan.scenes.builtin.primitives import n_splats_for_spacing

    path = _write(tmp_path, "s.yaml", SCENE)
    rc = main(["scene", "from-moveit", str(path), "--out", str(tmp_path / "x.ply"), "--spacing", "0.01", "--seed", "3"])
    assert rc == 0, capsys.readouterr().err
    gt = AnalyticScene.load(tmp_path / "x.gt.json")
    assert gt.meta["n_splats"] == n_splats_for_spacing(load_moveit_scene(path), 0.01, seed=3)
    assert 0.009 <= gt.meta["base_spacing"] <= 0.01
    capsys.readouterr()
    for extra, msg in ((["--spacing", "0.01", "--n-splats", "5000"], "not both"), (["--spacing", "5"], "smaller spacing"),
                       (["--spacing", "1e-6"], "larger --spacing")):  # fmt: skip
        rc = main(["scene", "from-moveit", str(path), "--out", str(tmp_path / "y.ply"), *extra])
        err = capsys.readouterr().err
        assert rc == 2 and msg in err and err.count("\n") == 1, (extra, err)
        assert not (tmp_path / "y.ply").exists()
    assert main(["scene", "stonehenge", "--out", str(tmp_path / "z.ply"), "--spacing", "0.01"]) == 2
    assert "goes with 'splatplan scene from-moveit" in capsys.readouterr().err
