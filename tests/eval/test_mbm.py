"""`splatplan eval mbm`: smoke test on a few MBM problems (skipped without the shared data), plus
the pieces the rows rely on: dense path resampling, exact clearance with the broad phase, the
derived margin, the config's validation."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main
from splatplan.errors import SplatplanError
from splatplan.eval.mbm import MBMConfig, dense_path, derived_margin, exact_clearance, summarise
from splatplan.robots import load_robot
from splatplan.scenes.builtin.primitives import AnalyticScene, make_box, make_cylinder

REPO = Path(__file__).resolve().parents[2]
MBM = REPO / ".." / "shared" / "data" / "mbm"
needs_mbm = pytest.mark.skipif(not (MBM / "problems").is_dir(), reason=f"{MBM} not present")

ROW_FIELDS = ("family", "index", "start_valid", "goal_valid", "start_free", "goal_free", "solved", "time_s", "n_nodes",
              "path_length", "path", "min_exact_clearance_m")  # fmt: skip


@needs_mbm
def test_eval_mbm_quick_cli(tmp_path, capsys):
    out = tmp_path / "mbm"
    rc = main(["eval", "mbm", "--quick", "--families", "box,table_pick", "--n-splats", "10000", "--time-limit", "2", "--margin-m", "0", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    d = json.loads((out / "mbm.json").read_text())
    assert [r["family"] for r in d["rows"]] == ["box", "table_pick"] and d["rows"][0]["index"] == 1
    for r in d["rows"]:
        assert all(k in r for k in ROW_FIELDS)
        assert r["solved"] == (r["path"] is not None)
        if r["solved"]:
            assert np.isfinite(r["min_exact_clearance_m"]) and r["time_s"] > 0
    assert set(d["summary"]) == {"box", "table_pick", "overall"} and "VAMP" in d["published"]
    md = (out / "mbm.md").read_text()
    assert "| overall |" in md and "VAMP" in md and "cuRobo" in md


def test_eval_mbm_bad_input(tmp_path, capsys):
    rc = main(["eval", "mbm", "--problems", str(tmp_path / "nope"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "not found" in err and err.count("\n") == 1
    with pytest.raises(SplatplanError):
        MBMConfig(n_per_family=0).validate()


def test_dense_path_resolution():
    robot = load_robot("panda")
    rng = np.random.default_rng(0)
    lo, hi = robot.joint_limits[:, 0], robot.joint_limits[:, 1]
    path = lo + rng.random((4, 7)) * (hi - lo)
    dense = dense_path(robot, path)
    np.testing.assert_array_equal(dense[0], path[0])
    np.testing.assert_allclose(dense[-1], path[-1], atol=1e-12)
    step = np.abs(np.diff(dense, axis=0)) @ robot.motion_bound
    assert step.max() <= 0.25 * robot.min_semi_axis + 1e-12
    # every original vertex is a sample (the path's shape is kept)
    for v in path:
        assert np.min(np.abs(dense - v).sum(axis=1)) < 1e-12


def test_exact_clearance_broad_phase_matches_all_pairs():
    robot = load_robot("panda")
    scene = AnalyticScene(np.stack([make_box([0.5, 0, 0.2], [0.1, 0.3, 0.2]), make_box([0, 0, -0.05], [1, 1, 0.05])]), [], {},
                          make_cylinder([0.3, 0.3, 0.5], 0.04, 0.1)[None])  # fmt: skip
    rng = np.random.default_rng(1)
    lo, hi = robot.joint_limits[:, 0], robot.joint_limits[:, 1]
    q = lo + rng.random((6, 7)) * (hi - lo)
    c, quat, a = robot.ellipsoids(q)
    ref = scene.ellipsoid_clearance(c, quat, a).min(axis=1)
    np.testing.assert_allclose(exact_clearance(scene, robot, q), ref, atol=1e-12)


def test_derived_margin():
    robot = load_robot("panda")
    means = np.random.default_rng(2).random((2000, 3))
    m, h, r = derived_margin(robot, means, 3.0)
    assert r == pytest.approx(0.25 * robot.min_semi_axis) and m == pytest.approx(3.0 * h + 0.5 * r)
    assert 0 < h < 0.2


def test_summarise_counts():
    row = dict(start_valid=True, goal_valid=False, start_free=True, goal_free=True, start_free_unmargined=True, goal_free_unmargined=True,
               solved=True, time_s=1.0, min_exact_clearance_m=-0.001, margin_m=0.01, rho_measured_m=0.005, bound_holds=True)  # fmt: skip
    s = summarise([row, {**row, "goal_free": False, "solved": False}])
    assert s["valid_endpoints"] == 2 and s["free_endpoints"] == 3 and s["problems_both_free"] == 1
    assert s["solved"] == 1 and s["negative_clearance_paths"] == 1 and s["worst_exact_clearance_m"] == -0.001


SCENE_YAML = """world:
  collision_objects:
    - id: table
      primitives: [{type: box, dimensions: [1.0, 1.0, 0.04]}]
      primitive_poses: [{position: [0.6, 0.0, -0.3], orientation: [0, 0, 0, 1]}]
    - id: can
      primitives: [{type: cylinder, dimensions: [0.12, 0.03]}]
      primitive_poses: [{position: [0.6, 0.3, -0.22], orientation: [0, 0, 0, 1]}]
"""
START = "start_state: {joint_state: {name: [panda_joint1, panda_joint2, panda_joint3, panda_joint4, panda_joint5, panda_joint6, panda_joint7, panda_finger_joint1], position: [0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.04]}}\n"


@pytest.mark.parametrize(
    "goal, msg",
    [
        ("[0, -0.785, 0, 0.5, 0, 1.571, 0.785]", "panda_joint4 = 0.5, 0.5698 above its upper limit -0.0698"),
        ("[0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.1]", "names joint(s) 'elbow_extra'"),
    ],
)
def test_eval_mbm_bad_requests_exit_2(tmp_path, capsys, goal, msg):
    """A request that does not fit the robot stops the benchmark with one line (exit 2)."""
    fam = tmp_path / "problems" / "toy_panda"
    fam.mkdir(parents=True)
    (fam / "scene0001.yaml").write_text(SCENE_YAML)
    vals = json.loads(goal)
    names = [f"panda_joint{i}" for i in range(1, 8)] + (["elbow_extra"] if len(vals) == 8 else [])
    cons = ", ".join(f"{{joint_name: {n}, position: {v}}}" for n, v in zip(names, vals))
    (fam / "request0001.yaml").write_text(START + f"goal_constraints: [{{joint_constraints: [{cons}]}}]\n")
    rc = main(["eval", "mbm", "--problems", str(tmp_path / "problems"), "--families", "toy", "--robot", "panda", "--n-splats", "5000",
               "--out", str(tmp_path / "o")])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and msg in err and err.count("\n") == 1, err
