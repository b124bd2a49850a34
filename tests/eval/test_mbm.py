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
from splatplan.eval.mbm import (TIMING_FIELDS, MBMConfig, MBMContext, MBMTask, check_inputs, covering_radius, dense_path, derived_margin, exact_clearance,
                                path_min_clearance, run_mbm, solve_problem, summarise)
from splatplan.eval._mbm_config import MBM_DATA_ENV, mbm_data_dir
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
    # above n_sigma 0 the estimate of rho shrinks by n_sigma x the median middle std, down to the floor
    scales = np.tile([0.6 * h, 0.5 * h, 0.01 * h], (2000, 1))  # middle std 0.5 h
    m1, h1, _ = derived_margin(robot, means, 3.0, n_sigma=2.0, scales=scales, floor_factor=0.5)
    assert h1 == h and m1 == pytest.approx(2.0 * h + 0.5 * r)
    m9, _, _ = derived_margin(robot, means, 3.0, n_sigma=9.0, scales=scales, floor_factor=0.5)
    assert m9 == pytest.approx(0.5 * h + 0.5 * r)


def _toy_scene():
    return AnalyticScene(np.stack([make_box([0.5, 0, 0.2], [0.1, 0.3, 0.2]), make_box([0, 0, -0.05], [1, 1, 0.05])]), [], {},
                         make_cylinder([0.3, 0.3, 0.5], 0.04, 0.1)[None])  # fmt: skip


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_path_min_clearance_matches_every_configuration(seed):
    """The branch and bound over a dense path gives the min of the per-configuration clearances."""
    robot = load_robot("panda")
    scene = _toy_scene()
    rng = np.random.default_rng(seed)
    lo, hi = robot.joint_limits[:, 0], robot.joint_limits[:, 1]
    mid = lo + (0.3 + 0.4 * rng.random(7)) * (hi - lo)
    path = np.stack([mid, mid + 0.15 * (rng.random(7) - 0.5) * (hi - lo), mid + 0.15 * (rng.random(7) - 0.5) * (hi - lo)])
    dense = dense_path(robot, path)
    ref = exact_clearance(scene, robot, dense).min()
    assert path_min_clearance(scene, robot, dense) == pytest.approx(ref, abs=1e-9)
    assert path_min_clearance(scene, robot, dense, first=1, stride=3) == pytest.approx(ref, abs=1e-9)


def test_covering_radius_against_brute_force():
    """rho(n_sigma): the max over surface samples of the distance to the nearest splat n_sigma-ellipsoid,
    checked against an all-splats computation; it shrinks as n_sigma grows."""
    from splatplan.scenes.builtin.primitives import project_to_ellipsoid, sample_faces, splats_from_scene
    from splatplan.scenes.splats import quat_to_rotmat

    scene = AnalyticScene(make_box([0, 0, 0], [0.1, 0.08, 0.05])[None], [], {})
    splats = splats_from_scene(scene, 150, seed=3)
    spacing = float(splats.info["base_spacing"])
    rhos = [covering_radius(scene, splats, spacing, n_sigma=n, seed=0, oversample=1.0, k=len(splats)) for n in (0.0, 1.0, 2.0)]
    assert rhos[0] > rhos[1] > rhos[2] >= 0
    x = sample_faces(scene, np.full(1, spacing), np.ones((1, 6), bool), np.random.default_rng(0), curved_spacing=spacing)["p"]
    mu, rot = splats.means.astype(np.float64), quat_to_rotmat(splats.quats.astype(np.float64)).reshape(-1, 3, 3)
    assert rhos[0] == pytest.approx(np.linalg.norm(x[:, None] - mu[None], axis=2).min(axis=1).max())
    u = np.einsum("nji,pnj->pni", rot, x[:, None] - mu[None]).reshape(-1, 3)  # every (sample, splat) pair
    semi = np.broadcast_to(1.0 * np.maximum(splats.scales.astype(np.float64), 1e-12), (len(x), len(mu), 3)).reshape(-1, 3)
    brute = np.linalg.norm(u - project_to_ellipsoid(u, semi), axis=1).reshape(len(x), -1).min(axis=1).max()
    assert rhos[1] == pytest.approx(brute, rel=1e-6)


def test_summarise_counts():
    row = dict(start_valid=True, goal_valid=False, start_free=True, goal_free=True, start_free_unmargined=True, goal_free_unmargined=True,
               solved=True, time_s=1.0, min_exact_clearance_m=-0.001, margin_m=0.01, rho_measured_m=0.005, bound_holds=True)  # fmt: skip
    s = summarise([row, {**row, "goal_free": False, "solved": False}])
    assert s["valid_endpoints"] == 2 and s["free_endpoints"] == 3 and s["problems_both_free"] == 1
    assert s["solved"] == 1 and s["negative_clearance_paths"] == 1 and s["worst_exact_clearance_m"] == -0.001
    assert s["solved_late"] is None  # a wall-clock run: nothing is late
    assert summarise([row], time_limit=0.5)["solved_late"] == 1 and summarise([row], time_limit=2.0)["solved_late"] == 0
    near = {**row, "goal_free": False, "start_clearance_m": 0.2, "goal_clearance_m": 0.004}  # goal 4 mm from the can, margin 10 mm
    far = {**near, "goal_clearance_m": 0.03}  # not free for another reason (a splat off the surface)
    assert summarise([near, far, row])["not_free_below_margin"] == 1


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


def test_tasks_carry_the_parsed_problem(tmp_path):
    """check_inputs parses every YAML once; a worker solving the task from what it carries gives the
    same row as one reading the files, and with an iteration budget a rerun gives the same row."""
    fam = tmp_path / "problems" / "toy_panda"
    fam.mkdir(parents=True)
    (fam / "scene0001.yaml").write_text(SCENE_YAML)
    cons = ", ".join(f"{{joint_name: panda_joint{i}, position: {v}}}" for i, v in enumerate([0.3, -0.5, 0, -2.0, 0, 1.571, 0.785], 1))
    (fam / "request0001.yaml").write_text(START + f"goal_constraints: [{{joint_constraints: [{cons}]}}]\n")
    cfg = MBMConfig(problems=str(tmp_path / "problems"), families=("toy",), robot="panda", n_splats=5000, margin_m=0.0, max_iters=50).validate()
    robot = load_robot("panda")
    bare = MBMTask("toy", 1, str(fam / "scene0001.yaml"), str(fam / "request0001.yaml"))
    (task,) = check_inputs([bare], robot)
    assert task.objects is not None and len(task.q_start) == len(task.q_goal) == 7
    json.dumps(task.objects)  # plain data: ships to a worker as is
    (fam / "scene0001.yaml").unlink()  # the worker never reads the files
    (fam / "request0001.yaml").unlink()
    row = solve_problem(task, MBMContext(cfg, robot))
    again = solve_problem(task, MBMContext(cfg, robot))
    assert row["start_free"] and row["goal_free"] and row["timed_out"] is False
    drop = TIMING_FIELDS
    same = [json.dumps({k: v for k, v in r.items() if k not in drop}, sort_keys=True) for r in (row, again)]  # NaN-safe
    assert same[0] == same[1]


def test_ball_clearance_needs_no_solve():
    """A ball (a sphere model's link) apart from the primitives has clearance d_c - radius exactly:
    the shortcut agrees with the solver, per configuration and along a path."""
    robot = load_robot("sphere:0.05")
    scene = _toy_scene()
    rng = np.random.default_rng(4)
    q = np.array([-0.6, -0.6, 0.0]) + rng.random((40, 3)) * np.array([1.6, 1.6, 1.0])  # centres, some inside
    c, quat, a = robot.ellipsoids(q)
    ref = scene.ellipsoid_clearance(c, quat, a).min(axis=1)
    np.testing.assert_allclose(exact_clearance(scene, robot, q), ref, atol=1e-7)
    path = np.linspace([0.9, 0.9, 0.6], [0.8, -0.9, 0.7], 50)
    assert path_min_clearance(scene, robot, path) == pytest.approx(scene.ellipsoid_clearance(*robot.ellipsoids(path)).min(), abs=1e-7)


def test_isolated_filter_drops_only_the_samplers_floaters():
    """MBMConfig.drop_isolated: on a dense MoveIt-style scene the isolated-splat rule drops floaters
    only (the sampler appends them last), most of those the paper's size rule keeps, and never a
    surface splat; the prepared scene is the filtered one and says how many it dropped."""
    from splatplan.eval.mbm import _prepare
    from splatplan.scenes.filters import filter_floaters, isolated_mask
    from splatplan.scenes.moveit import build_moveit

    scene = _toy_scene()
    splats, _ = build_moveit(scene, n_splats=200_000, seed=3)
    n_float = int(splats.info["n_floaters"])
    is_floater = np.arange(len(splats)) >= len(splats) - n_float
    kept, _ = filter_floaters(splats)
    kept_floater = np.isin(kept.means.view("V12").ravel(), splats.means[is_floater].view("V12").ravel())
    iso = isolated_mask(kept.means, kept.opacities)
    assert kept_floater.sum() >= 5  # the size rule leaves some for this test to be about
    assert not (iso & ~kept_floater).any()  # no surface splat dropped
    assert iso[kept_floater].mean() >= 0.8
    task = MBMTask("toy", 1, "", "", objects=scene.to_json())
    robot = load_robot("panda")
    prep = _prepare(task, MBMConfig(n_splats=200_000, seed=3), robot)
    assert prep.n_isolated == int(iso.sum()) and len(prep.splats) == len(kept) - prep.n_isolated
    off = _prepare(task, MBMConfig(n_splats=200_000, seed=3, drop_isolated=False), robot)
    assert off.n_isolated == 0 and len(off.splats) == len(kept)


def test_default_density_is_per_area():
    """MBMConfig samples each scene at splat_spacing_m (a count per area, so an unseen larger cell
    keeps the density and the margin), unless n_splats fixes the count; the rows say which."""
    from splatplan.eval.mbm import _prepare
    from splatplan.scenes.builtin.primitives import n_splats_for_spacing

    scene = _toy_scene()
    task = MBMTask("toy", 1, "", "", objects=scene.to_json())
    robot = load_robot("panda")
    prep = _prepare(task, MBMConfig(splat_spacing_m=0.01, seed=3), robot)
    assert MBMConfig().n_splats is None
    assert prep.n_sampled == n_splats_for_spacing(scene, 0.01, seed=3)
    assert 0.009 <= prep.base_spacing <= 0.01
    capped = _prepare(task, MBMConfig(splat_spacing_m=0.01, max_splats=2000, seed=3), robot)
    assert capped.n_sampled == 2000 and capped.base_spacing > 0.01
    fixed = _prepare(task, MBMConfig(n_splats=3000, seed=3), robot)
    assert fixed.n_sampled == 3000


def test_data_location_from_the_environment(tmp_path, monkeypatch):
    """The MBM data folder: $SPLATPLAN_MBM_DATA when set (an installed package has no checkout
    beside it); a missing folder is one line naming the flag and the variable."""
    from splatplan.errors import SplatplanError
    from splatplan.eval.mbm import MBM_DATA_ENV, mbm_data_dir

    (tmp_path / "problems" / "toy_panda").mkdir(parents=True)
    monkeypatch.setenv(MBM_DATA_ENV, str(tmp_path))
    assert mbm_data_dir() == tmp_path
    assert MBMConfig().problems_dir() == tmp_path / "problems"
    with pytest.raises(SplatplanError, match=f"--robot URDF or set {MBM_DATA_ENV}"):
        MBMConfig().robot_path()
    monkeypatch.setenv(MBM_DATA_ENV, str(tmp_path / "nowhere"))
    with pytest.raises(SplatplanError, match=f"--problems DIR .* or set {MBM_DATA_ENV}"):
        MBMConfig().problems_dir()


@pytest.mark.slow
@pytest.mark.skipif(not (mbm_data_dir() / "problems").is_dir(), reason=f"MBM data not found at {mbm_data_dir()} (set {MBM_DATA_ENV})")
def test_quick_defaults_solve_every_free_problem_safely():
    """``eval mbm --quick`` at its defaults (derived margin, the full run's splat spacing): as in the
    full run (benchmarks/results/mbm/), every problem whose endpoints are free for the planning model
    is solved, and no solved path comes closer than 0 to the exact geometry."""
    res = run_mbm(MBMConfig.quick(), progress=False)
    assert not res.failures and len(res.rows) == len(MBMConfig().families)
    free = [r for r in res.rows if r["start_free"] and r["goal_free"]]
    assert len(free) >= 2, [(r["family"], r["index"], r["message"]) for r in res.rows]  # the quick run plans something
    assert all(r["solved"] for r in free), [(r["family"], r["index"], r["message"]) for r in free if not r["solved"]]
    solved = [r for r in res.rows if r["solved"]]
    assert all(r["min_exact_clearance_m"] >= 0 for r in solved), [(r["family"], r["index"], r["min_exact_clearance_m"]) for r in solved]
    assert res.summary["overall"]["negative_clearance_paths"] == 0 and res.summary["overall"]["solved_of_started_frac"] == 1.0


@pytest.mark.slow
@pytest.mark.skipif(not (mbm_data_dir() / "problems").is_dir(), reason=f"MBM data not found at {mbm_data_dir()} (set {MBM_DATA_ENV})")
def test_blocked_grasp_goal_is_escaped_safely():
    """A grasp goal closer to the table than the margin (table_pick 7: blocked for the planning model)
    is left by an escape segment: the problem starts, is solved, the path ends exactly at the goal and
    keeps a positive exact clearance (the segment measured with the model it was checked with)."""
    from splatplan.eval.mbm import check_inputs, list_tasks, make_context, solve_problem

    cfg = MBMConfig(families=("table_pick",), n_per_family=7)
    ctx = make_context(cfg)
    assert ctx.escape_robot is not None and ctx.escape_robot.n_ellipsoids > ctx.robot.n_ellipsoids
    task = check_inputs([t for t in list_tasks(cfg) if t.index == 7], ctx.robot)[0]
    row = solve_problem(task, ctx)
    assert row["start_free"] and not row["goal_free"] and row["goal_escape"] is not None and row["started"], row["message"]
    assert row["solved"] and row["min_exact_clearance_m"] > 0, row
    path = np.asarray(row["path"])
    np.testing.assert_allclose(path[-1], task.q_goal, atol=1e-6)
    np.testing.assert_allclose(path[0], task.q_start, atol=1e-6)


@pytest.mark.slow
@pytest.mark.skipif(not (mbm_data_dir() / "problems").is_dir(), reason=f"MBM data not found at {mbm_data_dir()} (set {MBM_DATA_ENV})")
def test_a_goal_only_a_higher_n_sigma_frees_is_escaped_safely():
    """bookshelf_small 29: the wrist is 3 mm from the shelf at the goal, closer than rho(0) plus the
    finest r / 32 (blocked at n_sigma 0 at every divisor); the escape segment is checked at a higher
    n_sigma with rho(n) from the same splats, the problem is solved and the whole path keeps a
    positive exact clearance (the segment measured with the model it was checked with)."""
    from splatplan.eval.mbm import check_inputs, list_tasks, make_context, solve_problem
    from splatplan.planners.escape import endpoint_check

    cfg = MBMConfig(families=("bookshelf_small",), n_per_family=29)
    ctx = make_context(cfg)
    task = check_inputs([t for t in list_tasks(cfg) if t.index == 29], ctx.robot)[0]
    row = solve_problem(task, ctx)
    prep = ctx.prepared(task)
    margin = prep.splat_margin
    assert endpoint_check(prep.checker, ctx.escape_robot, np.asarray(task.q_goal), margin, n_sigmas=()) is None  # n_sigma 0 cannot
    assert row["start_free"] and not row["goal_free"] and row["started"], row["message"]
    assert row["goal_escape_n_sigma"] > 1.0 and row["goal_escape_n_sigma"] <= 3.0
    assert row["solved"] and row["min_exact_clearance_m"] > 0, row
    path = np.asarray(row["path"])
    np.testing.assert_allclose(path[-1], task.q_goal, atol=1e-6)


@pytest.mark.slow
@pytest.mark.skipif(not (mbm_data_dir() / "problems").is_dir(), reason=f"MBM data not found at {mbm_data_dir()} (set {MBM_DATA_ENV})")
def test_an_escape_with_no_segment_out_is_a_row_not_started(monkeypatch):
    """bookshelf_small 19: the goal's endpoint check passes (the escape model at a higher n_sigma);
    with every escape segment blocked (the segment search made to find nothing), the row says so (not
    started, the planner's message), no failure."""
    from splatplan.eval.mbm import check_inputs, list_tasks, make_context, solve_problem
    from splatplan.planners import escape

    monkeypatch.setattr(escape, "_segments", lambda *a, **k: (None, 0, len(a[3])))  # (no segment gets out)
    cfg = MBMConfig(families=("bookshelf_small",), n_per_family=19)
    ctx = make_context(cfg)
    task = check_inputs([t for t in list_tasks(cfg) if t.index == 19], ctx.robot)[0]
    row = solve_problem(task, ctx)
    assert not row["goal_valid"] and not row["started"] and not row["solved"] and row["path"] is None
    assert row["goal_escape"] is not None and row["goal_escape_n_sigma"] > 0  # the endpoint check passed, the segments did not
    assert row["message"].startswith("not started:") and "straight segments" in row["message"], row["message"]


@pytest.mark.slow
@pytest.mark.skipif(not (mbm_data_dir() / "problems").is_dir(), reason=f"MBM data not found at {mbm_data_dir()} (set {MBM_DATA_ENV})")
def test_a_goal_random_segments_cannot_leave_is_escaped_by_a_push():
    """bookshelf_small 19: the certified model is 0.7 mm into the shelf at the goal (an invalid
    endpoint for it), the escape model at a higher n_sigma is free there, and none of the first
    round's segments gets the planning model clear; the second round's push directions do. The
    problem is solved and the whole path keeps a positive exact clearance (the segment measured with
    the model it was checked with)."""
    from splatplan.eval.mbm import check_inputs, list_tasks, make_context, solve_problem

    cfg = MBMConfig(families=("bookshelf_small",), n_per_family=19)
    ctx = make_context(cfg)
    task = check_inputs([t for t in list_tasks(cfg) if t.index == 19], ctx.robot)[0]
    row = solve_problem(task, ctx)
    assert not row["goal_valid"] and row["goal_escape_n_sigma"] > 0
    assert row["started"] and row["solved"] and row["min_exact_clearance_m"] > 0, row["message"]
    np.testing.assert_allclose(np.asarray(row["path"])[-1], task.q_goal, atol=1e-6)


@pytest.mark.parametrize("yaml_text", [None, "ellipsoids: [oops"])
def test_eval_mbm_bad_escape_model_exit_2(tmp_path, capsys, yaml_text):
    """A missing or broken escape model stops the benchmark with one line naming it (exit 2)."""
    fam = tmp_path / "problems" / "toy_panda"
    fam.mkdir(parents=True)
    (fam / "scene0001.yaml").write_text(SCENE_YAML)
    cons = ", ".join(f"{{joint_name: panda_joint{i + 1}, position: {v}}}" for i, v in enumerate([0, -0.785, 0, -2.356, 0, 1.571, 0.785]))
    (fam / "request0001.yaml").write_text(START + f"goal_constraints: [{{joint_constraints: [{cons}]}}]\n")
    model = tmp_path / "escape.yaml"
    if yaml_text is not None:
        model.write_text(yaml_text)
    rc = main(["eval", "mbm", "--problems", str(tmp_path / "problems"), "--families", "toy", "--robot", "panda", "--n-splats", "5000",
               "--escape-ellipsoids", str(model), "--out", str(tmp_path / "o")])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "escape.yaml" in err and err.count("\n") == 1, err
