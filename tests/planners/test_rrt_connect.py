"""Batched RRT-Connect: paths verified by an independent dense check, determinism, the free-prefix
edge check against a per-sample reference, the planner dispatch, one deadline for the whole call
(refinement included) and the time split."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from splatplan.errors import PlanningError, SplatplanError
from splatplan.planners import (
    RRT,
    EdgeChecker,
    RefineConfig,
    RRTConfig,
    RRTConnect,
    edge_samples,
    make_planner,
    path_length,
    plan,
    refine_path,
    shortcut_path,
)
from splatplan.planners.robot_links import LinkGeometry

from .scenes import make_checker, make_scene, wall_scene

robots = pytest.importorskip("splatplan.robots")
SPHERE = robots.load_robot("sphere:0.015")

START = (-0.15, 0.0, 0.06)
GOAL = (0.15, 0.0, 0.06)
PLANE = dict(box_lo=(-0.25, -0.3, 0.06), box_hi=(0.25, 0.3, 0.06))
#: sealed: a closed box around the goal (0.2, 0, 0.06)
SEALED = [((-0.01, -0.25, 0.0), (0.01, 0.12, 0.12)), ((0.14, -0.06, 0.0), (0.26, 0.06, 0.12)),
          ((-0.3, -0.3, 0.0), (-0.28, -0.28, 0.12)), ((0.28, 0.28, 0.0), (0.3, 0.3, 0.12))]  # fmt: skip


@pytest.fixture(scope="module")
def wall():
    return make_checker(wall_scene(), n_sigma=1.0)


@pytest.fixture(scope="module")
def panda_table():
    # a table top under the Panda and a box on it, in front of the arm (metres, z up)
    scene = make_scene([((-0.3, -0.6, -0.12), (0.9, 0.6, -0.1)), ((0.25, -0.15, -0.1), (0.4, 0.15, 0.55))], spacing=0.03)
    return make_checker(scene, n_sigma=1.0)


def _dense_check(checker, robot, path: np.ndarray, res: float) -> bool:
    """Independent of the planner's EdgeChecker: every edge sampled so that no ellipsoid point
    moves more than ``res`` between samples (motion bound of the robot), vertices included, checked
    with ``robot.ellipsoids`` + ``checker.collides`` (host FK, not ``collides_robot``)."""
    geom = LinkGeometry(robot)
    qs = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, math.ceil(float(geom.motion(b - a)) / res))
        qs.append(a + (np.arange(1, n + 1) / n)[:, None] * (b - a))
    q = np.concatenate(qs)
    c, quat, ax = robot.ellipsoids(q)
    return not bool(np.asarray(checker.collides(c, quat, ax)).any())


def test_point_robot_around_wall(wall):
    robot = robots.load_robot("sphere:0.015")
    res = RRTConnect(wall, RRTConfig(seed=0, **PLANE), robot=robot).plan(START, GOAL)
    assert res.success, res.message
    np.testing.assert_allclose(res.path[0], START)
    np.testing.assert_allclose(res.path[-1], GOAL)
    assert np.max(res.path[:, 1]) > 0.12  # around the wall's open end
    np.testing.assert_allclose(res.path[:, 2], 0.06)
    assert res.length <= path_length(res.path_rrt) + 1e-12
    assert _dense_check(wall, robot, res.path, 0.015 / 8)
    assert _dense_check(wall, robot, res.path_rrt, 0.015 / 8)
    # both trees in one forest: two roots, parents before children
    par = res.tree_parents
    assert (par == -1).sum() == 2 and res.n_nodes == len(res.tree_nodes) == sum(res.info["tree_sizes"])


def test_panda_tabletop_path_is_free(panda_table):
    robot = robots.load_robot("panda")
    q1, q2 = robot.q_default.copy(), robot.q_default.copy()
    q1[0], q2[0] = 1.4, -1.4
    geom = LinkGeometry(robot)
    line = q1 + np.linspace(0, 1, 9)[:, None] * (q2 - q1)
    assert geom.collides(panda_table, line).any()  # the straight joint path hits the box
    res = plan(panda_table, q1, q2, robot=robot, refine=False, rrt_config=RRTConfig(time_limit_s=60.0))
    assert res.success, res.message
    assert res.info["planner"] == "rrtconnect"  # the default for 7 dofs
    np.testing.assert_allclose(res.path[0], q1)
    np.testing.assert_allclose(res.path[-1], q2)
    lim = robot.joint_limits
    assert np.all(res.path >= lim[:, 0] - 1e-12) and np.all(res.path <= lim[:, 1] + 1e-12)
    res_m = res.info["settings"]["edge_resolution"]
    assert res_m == pytest.approx(0.25 * robot.min_semi_axis)
    assert _dense_check(panda_table, robot, res.path, res_m)
    assert _dense_check(panda_table, robot, res.path_rrt, res_m)


def test_deterministic_for_a_seed(wall):
    cfg = RRTConfig(seed=3, **PLANE)
    a = RRTConnect(wall, cfg, robot=SPHERE).plan(START, GOAL)
    b = RRTConnect(wall, cfg, robot=SPHERE).plan(START, GOAL)
    assert a.success and b.success
    np.testing.assert_array_equal(a.path, b.path)
    np.testing.assert_array_equal(a.tree_nodes, b.tree_nodes)
    assert a.n_iters == b.n_iters


def test_free_prefix_matches_per_sample_reference(wall):
    robot = robots.load_robot("panda")
    ch = make_checker(make_scene([((0.3, -0.3, 0.0), (0.4, 0.3, 0.8))], spacing=0.03), n_sigma=1.0)
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(0)
    lim = robot.joint_limits
    a = lim[:, 0] + rng.random((12, 7)) * (lim[:, 1] - lim[:, 0])
    b = np.clip(a + rng.normal(scale=0.4, size=a.shape), lim[:, 0], lim[:, 1])
    edges = EdgeChecker(ch, geom, 0.25 * robot.min_semi_axis)
    k, n = edges.free_prefix(a, b)
    pts, idx, n_ref = edge_samples(a, b, geom.motion(b - a), edges.resolution)
    np.testing.assert_array_equal(n, n_ref)
    for e in range(len(a)):  # reference: each edge's samples on their own, the first hit by a scan
        hits = list(geom.collides(ch, pts[idx == e]))
        want = hits.index(True) if True in hits else len(hits)
        assert k[e] == want, (e, k[e], want)
    assert 0 < (k < n).sum() < len(a)  # the test sees both kinds
    np.testing.assert_array_equal(edges.edges_free(a, b), k == n)


def test_doubling_shortcut_keeps_vertices_and_never_lengthens(wall):
    res = RRTConnect(wall, RRTConfig(seed=1, shortcut=False, **PLANE), robot=SPHERE).plan(START, GOAL)
    edges = EdgeChecker(wall, RRT(wall, robot=SPHERE).geometry, res.info["edge_resolution"], inflate=True)
    short = shortcut_path(edges, res.path, candidates="doubling")
    assert path_length(short) <= path_length(res.path) + 1e-12
    np.testing.assert_allclose(short[[0, -1]], res.path[[0, -1]])
    assert all(np.any(np.all(res.path == v, axis=1)) for v in short)  # vertices of the input
    assert edges.path_free(short)
    with pytest.raises(SplatplanError, match="candidates"):
        shortcut_path(edges, res.path, candidates="some")


def test_make_planner_auto_and_bad_name(wall):
    assert isinstance(make_planner("auto", wall, robot="panda"), RRTConnect)
    p = make_planner("auto", wall, robot="sphere:0.015")
    assert type(p) is RRT and p.name == "rrt"
    assert type(make_planner("auto", wall, robot="go2")) is RRTConnect  # a planar base: RRT-Connect, like an arm
    assert isinstance(make_planner("RRT-Connect", wall, robot=SPHERE), RRTConnect)
    with pytest.raises(SplatplanError, match="unknown planner 'prm'.*auto, rrt, rrtconnect"):
        make_planner("prm", wall, robot=SPHERE)
    with pytest.raises(PlanningError, match="needs a goal"):
        RRTConnect(wall, robot=SPHERE).plan(START, None)


def test_time_limit_covers_the_whole_call_and_split_sums():
    ch = make_checker(make_scene(SEALED, spacing=0.008), n_sigma=1.0)
    limit = 0.3
    for name in ("rrt", "rrtconnect"):
        t = time.perf_counter()
        res = plan(ch, (-0.15, 0.0, 0.06), (0.2, 0.0, 0.06), robot=SPHERE, planner=name, rrt_config=RRTConfig(time_limit_s=limit, **PLANE))
        wall_s = time.perf_counter() - t
        assert not res.success and res.info.get("time_limit_hit")
        assert wall_s < limit + 2.0  # generous slack: never assert tight timings
        split = res.info["time_split"]
        assert set(split) == {"sampling", "nearest", "collision", "shortcut", "refine", "other"}
        assert all(v >= 0 for v in split.values())
        assert sum(split.values()) <= res.time_s * (1 + 1e-6) + 1e-6


def test_refinement_stops_at_the_deadline(panda_table):
    robot = robots.load_robot("panda")
    q1, q2 = robot.q_default.copy(), robot.q_default.copy()
    q1[0], q2[0] = 1.4, -1.4
    res = plan(panda_table, q1, q2, robot=robot, refine=False, rrt_config=RRTConfig(time_limit_s=60.0))
    assert res.success
    # a deadline in the past: the refinement keeps the input path and says why
    ref = refine_path(panda_table, res.path, robot=robot, config=RefineConfig(n_samples=64), deadline=time.perf_counter())
    assert not ref.accepted and "time limit" in ref.message
    np.testing.assert_array_equal(ref.path, res.path)
    # the whole call with refinement stays within a small limit (search included)
    limit = 1.0
    t = time.perf_counter()
    res2 = plan(panda_table, q1, q2, robot=robot, refine=True, rrt_config=RRTConfig(time_limit_s=limit))
    assert time.perf_counter() - t < limit + 2.0
    split = res2.info["time_split"]
    assert sum(split.values()) <= res2.time_s * (1 + 1e-6) + 1e-6


def test_budgets_end_the_search():
    ch = make_checker(make_scene(SEALED, spacing=0.008), n_sigma=1.0)
    s, g = (-0.15, 0.0, 0.06), (0.2, 0.0, 0.06)
    res = RRTConnect(ch, RRTConfig(max_iters=3, time_limit_s=None, **PLANE), robot=SPHERE).plan(s, g)
    assert not res.success and res.n_iters == 3 and "iteration budget" in res.message
    assert res.path.shape == (0, 3) and res.length == math.inf
    res = RRTConnect(ch, RRTConfig(max_nodes=40, time_limit_s=None, **PLANE), robot=SPHERE).plan(s, g)
    assert not res.success and "node budget" in res.message


def test_batch_size_defaults_per_planner_and_an_explicit_one_wins():
    ch = make_checker(wall_scene(), 0.0)
    assert RRTConfig().batch_size is None
    assert RRT(ch, robot=SPHERE).batch_size == 32 and RRTConnect(ch, robot=SPHERE).batch_size == 16
    assert RRT(ch, RRTConfig(batch_size=8), robot=SPHERE).batch_size == 8
    assert RRTConnect(ch, RRTConfig(batch_size=40), robot=SPHERE).batch_size == 40
    with pytest.raises(SplatplanError, match="batch_size"):
        RRTConfig(batch_size=0).validate()
