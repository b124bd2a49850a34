"""Lazy RRT-Connect and the screened shortcut: the same guarantee as the eager search (every edge of
the returned path checked at the edge resolution, verified here by an independent dense check),
fewer configurations checked; subtree removal of the trees; a screened shortcut returns the very
path of an unscreened one."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.planners import RRT, EdgeChecker, RRTConfig, RRTConnect, plan, shortcut_path
from splatplan.planners.robot_links import LinkGeometry
from splatplan.planners.trees import Tree

from .scenes import make_checker, make_scene, wall_scene
from .test_rrt_connect import GOAL, PLANE, START, _dense_check

robots = pytest.importorskip("splatplan.robots")
SPHERE = robots.load_robot("sphere:0.015")


@pytest.fixture(scope="module")
def wall():
    return make_checker(wall_scene(), n_sigma=1.0)


@pytest.fixture(scope="module")
def panda_table():
    scene = make_scene([((-0.3, -0.6, -0.12), (0.9, 0.6, -0.1)), ((0.25, -0.15, -0.1), (0.4, 0.15, 0.55))], spacing=0.03)
    return make_checker(scene, n_sigma=1.0)


def test_tree_invalidate_removes_whole_subtrees():
    t = Tree(np.zeros(2), np.ones(2), cap=2)  # grows past its capacity
    # 0 - 1 - 2 - 3, 1 - 4, 0 - 5 - 6
    t.add(np.array([[1.0, 0], [2, 0], [3, 0]]), np.array([0, 1, 2]), verified=False)
    t.add(np.array([[1.0, 1]]), np.array([1]))
    t.add(np.array([[-1.0, 0], [-2, 0]]), np.array([0, 5]), verified=False)
    assert t.n == 7 and t.verified[[0, 4]].all() and not t.verified[[1, 2, 3, 5, 6]].any()
    assert t.invalidate(np.array([2])) == 2  # 2 and 3
    np.testing.assert_array_equal(t.valid[: t.n], [1, 1, 0, 0, 1, 1, 1])
    assert t.invalidate(np.array([1, 0])) == 2  # the root stays; 1 and 4 go
    np.testing.assert_array_equal(t.valid[: t.n], [1, 0, 0, 0, 0, 1, 1])
    # removed nodes are never the nearest, even right on top of them
    np.testing.assert_array_equal(t.nearest(np.array([[3.0, 0.0], [1.0, 1.0], [-2.0, 0.0]])), [0, 0, 6])
    np.testing.assert_array_equal(t.trace_ids(6), [0, 5, 6])


def _configs(res, robot) -> int:
    return res.info["n_queries"] // robot.n_ellipsoids


def test_lazy_panda_path_verified_and_cheaper_than_eager(panda_table):
    robot = robots.load_robot("panda")
    q1, q2 = robot.q_default.copy(), robot.q_default.copy()
    q1[0], q2[0] = 1.4, -1.4
    out = {}
    for lazy in (True, False):
        res = plan(panda_table, q1, q2, robot=robot, refine=False, seed=2, rrt_config=RRTConfig(time_limit_s=60.0, lazy=lazy))
        assert res.success, res.message
        r = res.info["settings"]["edge_resolution"]
        assert _dense_check(panda_table, robot, res.path, r)
        assert _dense_check(panda_table, robot, res.path_rrt, r)
        out[lazy] = res
    assert "lazy" in out[True].info and "lazy" not in out[False].info
    assert _configs(out[True], robot) < _configs(out[False], robot)


def test_lazy_removes_edges_that_jump_a_wall(wall):
    # a stride far longer than the wall is thick: node checks alone cannot see the wall, so candidate
    # paths through it are found, rejected at the edge resolution and their subtrees removed
    rejected = 0
    for seed in range(4):
        res = RRTConnect(wall, RRTConfig(seed=seed, stride=0.12, **PLANE), robot=SPHERE).plan(START, GOAL)
        assert res.success, res.message
        assert _dense_check(wall, SPHERE, res.path_rrt, 0.015 / 8)
        assert _dense_check(wall, SPHERE, res.path, 0.015 / 8)
        assert np.max(res.path[:, 1]) > 0.12  # around the wall's open end, never through it
        rejected += res.info["lazy"]["edges_rejected"]
    assert rejected > 0


def test_screened_shortcut_returns_the_same_path_with_fewer_checks(panda_table):
    """Screening never changes the shortcut path. It saves checks where whole-edge checks check
    every sample (no free slack); with the free slack, whole-edge checks skip most samples near
    surfaces too, and only a sparse screen (the planners' every 64th sample) still saves checks."""
    robot = robots.load_robot("panda")
    q1, q2 = robot.q_default.copy(), robot.q_default.copy()
    q1[0], q2[0] = 1.4, -1.4
    res = RRTConnect(panda_table, RRTConfig(seed=0, shortcut=False), robot=robot).plan(q1, q2)
    assert res.success and len(res.path) > 4
    r = res.info["edge_resolution"]
    paths, counts = {}, {}
    for slack in (False, True):
        for screen in (None, 4, 16, 64):
            for cand in ("doubling", "all"):
                geom = LinkGeometry(robot)
                edges = EdgeChecker(panda_table, geom, r, stages=4, slack=slack)
                paths[slack, screen, cand] = shortcut_path(edges, res.path, candidates=cand, screen=screen)
                counts[slack, screen, cand] = geom.n_queries
    for slack in (False, True):
        for cand in ("doubling", "all"):
            for screen in (4, 16, 64):
                np.testing.assert_array_equal(paths[slack, screen, cand], paths[False, None, cand])
    for cand in ("doubling", "all"):
        assert counts[False, 16, cand] < counts[False, None, cand]
        assert counts[True, 64, cand] < counts[True, None, cand] < counts[False, None, cand]
    assert _dense_check(panda_table, robot, paths[True, 16, "all"], r)


def test_screen_never_rejects_a_free_edge(wall):
    geom = RRT(wall, robot=SPHERE).geometry
    edges = EdgeChecker(wall, geom, 0.004)
    rng = np.random.default_rng(0)
    a = rng.uniform((-0.25, -0.3, 0.06), (0.25, 0.3, 0.06), size=(40, 3))
    b = rng.uniform((-0.25, -0.3, 0.06), (0.25, 0.3, 0.06), size=(40, 3))
    ok = geom.collides(wall, a) | geom.collides(wall, b)
    a, b = a[~ok], b[~ok]
    free = edges.edges_free(a, b)
    for every in (1, 3, 8):
        s = edges.screen(a, b, every)
        assert np.all(s[free])  # a free edge always passes
    assert not np.all(edges.screen(a, b, 1)[~free])  # every sample but the end: hits are seen
    assert 0 < free.sum() < len(a)
