"""Batched RRT on small synthetic scenes: paths around a wall, edge validity, errors, exploration."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import PlanningError
from splatplan.metric import CollisionChecker
from splatplan.planners import RRT, EdgeChecker, RRTConfig, edge_points, path_length, plan, shortcut_path
from splatplan.robots import load_robot

from .scenes import make_checker, make_scene, wall_scene

R = 0.015
SPHERE = load_robot(f"sphere:{R}")
START = (-0.15, 0.0, 0.06)
GOAL = (0.15, 0.0, 0.06)
PLANE = dict(box_lo=(-0.25, -0.3, 0.06), box_hi=(0.25, 0.3, 0.06))


@pytest.fixture(scope="module")
def checker():
    return make_checker(wall_scene(), n_sigma=1.0)


def _dense_free(checker, path, res=R / 2):
    return EdgeChecker(checker, RRT(checker, robot=SPHERE).geometry, res).path_free(path)


def test_edge_points_spacing():
    a = np.zeros((2, 3))
    b = np.array([[0.1, 0, 0], [0.0, 0.02, 0]])
    pts = edge_points(a, b, 0.03)
    assert pts.shape == (2, 4, 3)
    np.testing.assert_allclose(pts[:, -1], b)
    assert np.linalg.norm(np.diff(pts[0], axis=0), axis=1).max() <= 0.03 + 1e-12


@pytest.mark.parametrize("shortcut", [False, True])
def test_finds_path_around_wall(checker, shortcut):
    res = RRT(checker, RRTConfig(shortcut=shortcut, seed=1, **PLANE), robot=SPHERE).plan(START, GOAL)
    assert res.success, res.message
    np.testing.assert_allclose(res.path[0], START)
    np.testing.assert_allclose(res.path[-1], GOAL)
    assert res.length > 0.3 + 0.05  # the straight line is blocked by the wall
    assert np.max(res.path[:, 1]) > 0.12  # goes around the open end of the wall
    assert _dense_free(checker, res.path)  # every edge collision-free at resolution r/2
    np.testing.assert_allclose(res.path[:, 2], 0.06)  # plane freezing keeps z fixed
    np.testing.assert_allclose(res.tree_nodes[:, 2], 0.06)
    assert res.n_nodes == len(res.tree_nodes) == len(res.tree_parents)
    assert res.time_s > 0 and res.n_iters > 0
    if shortcut:
        assert len(res.path) <= len(res.path_rrt)
        assert res.length <= path_length(res.path_rrt) + 1e-12


def test_tree_is_consistent(checker):
    res = RRT(checker, RRTConfig(seed=2, **PLANE), robot=SPHERE).plan(START, GOAL)
    par = res.tree_parents
    assert par[0] == -1 and np.all(par[1:] >= 0) and np.all(par[1:] < np.arange(1, len(par)))
    step = np.linalg.norm(res.tree_nodes[1:] - res.tree_nodes[par[1:]], axis=1)
    # stride bounds every edge except the final edge to the goal (connect_radius)
    assert np.sum(step > 0.03 + 1e-9) <= 1


def test_start_or_goal_in_collision_raises(checker):
    inside = (0.0, 0.0, 0.06)  # in the wall
    with pytest.raises(PlanningError, match="start .* in collision: min_s2"):
        RRT(checker, RRTConfig(**PLANE), robot=SPHERE).plan(inside, GOAL)
    with pytest.raises(PlanningError, match="goal .* in collision"):
        RRT(checker, RRTConfig(**PLANE), robot=SPHERE).plan(START, inside)
    with pytest.raises(PlanningError, match="outside the sampling box"):
        RRT(checker, RRTConfig(**PLANE), robot=SPHERE).plan((-0.15, 0.0, 0.07), GOAL)


def test_exploration_mode_edges_collision_free(checker):
    cfg = RRTConfig(max_nodes=400, seed=3, **PLANE)
    res = RRT(checker, cfg, robot=SPHERE).plan(START, None)
    assert res.success and len(res.path) == 0
    assert 300 <= res.n_nodes <= 400
    nodes, par = res.tree_nodes, res.tree_parents
    ec = EdgeChecker(checker, RRT(checker, robot=SPHERE).geometry, R / 2)
    assert ec.edges_free(nodes[par[1:]], nodes[1:]).all()
    np.testing.assert_allclose(nodes[:, 2], 0.06)
    # the tree explores both sides of the wall
    assert (nodes[:, 0] > 0.05).any() and (nodes[:, 0] < -0.05).any()


def test_budget_exhausted_reports_failure(checker):
    res = RRT(checker, RRTConfig(max_iters=2, seed=0, **PLANE), robot=SPHERE).plan(START, GOAL)
    assert not res.success and "iteration budget" in res.message and res.length == np.inf


def test_shortcut_never_collides_and_never_longer(checker):
    res = RRT(checker, RRTConfig(shortcut=False, seed=4, **PLANE), robot=SPHERE).plan(START, GOAL)
    ec = EdgeChecker(checker, RRT(checker, robot=SPHERE).geometry, R / 2)
    sc = shortcut_path(ec, res.path)
    assert path_length(sc) <= path_length(res.path) + 1e-12
    assert ec.path_free(sc)


def test_planar_base_rrt_over_x_y_yaw():
    # an ellipsoidal quadruped body over configurations (x, y, yaw) at a fixed height
    ch = make_checker(wall_scene(), n_sigma=0.5)
    lift = np.eye(4)
    lift[2, 3] = 0.06
    body = load_robot("ellipsoid:0.03,0.015,0.012", base="planar", base_pose=lift)  # PlanarBase(height=0.06)'s body
    cfg = RRTConfig(box_lo=(-0.25, -0.3, -np.pi), box_hi=(0.25, 0.3, np.pi), seed=0, edge_resolution=0.006)
    res = RRT(ch, cfg, robot=body).plan((-0.15, 0.0, 0.0), (0.15, 0.0, 0.0))
    assert res.success
    c, q, a = body.ellipsoids(res.path)
    assert not ch.collides(c, q, a).any()


def test_plan_convenience_refines(checker):
    res = plan(checker, START, GOAL, robot=SPHERE, rrt_config=RRTConfig(**PLANE), seed=0)
    assert res.success and res.refined
    assert res.length <= res.info["length_rrt"] + 1e-9
    assert _dense_free(checker, res.path)


def test_plan_result_typed_views(checker):
    """The extras users read are typed properties of PlanResult, equal to the info dict's entries."""
    res = plan(checker, START, GOAL, robot=SPHERE, rrt_config=RRTConfig(**PLANE), seed=0)
    assert res.planner == res.info["planner"] == "rrt"
    assert isinstance(res.n_configs, int) and res.n_configs == res.info["n_configs"] > 0
    assert set(res.time_split) >= {"sampling", "nearest", "collision", "shortcut", "refine", "other"}
    assert abs(sum(res.time_split.values()) - res.time_s) < 1e-6
    assert res.settings and res.settings == res.info["settings"]
    assert res.length_shortcut == res.info["length_rrt"] >= res.length - 1e-9
    np.testing.assert_array_equal(res.path_shortcut, res.info["path_shortcut"])
    assert isinstance(res.refine_message, str) and res.refine_message


def test_backend_independent():
    """Same seed -> same tree with the numpy reference and (when present) the Warp kernel."""
    s = make_scene([((-0.01, -0.1, 0.0), (0.01, 0.05, 0.12))])
    ref = CollisionChecker(s, n_sigma=1.0, backend="reference")
    other = make_checker(s, n_sigma=1.0)
    cfg = RRTConfig(max_nodes=150, seed=5, **PLANE)
    a = RRT(ref, cfg, robot=SPHERE).plan(START, None)
    b = RRT(other, cfg, robot=SPHERE).plan(START, None)
    np.testing.assert_allclose(a.tree_nodes, b.tree_nodes)
