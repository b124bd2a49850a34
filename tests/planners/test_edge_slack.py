"""Edge checks that skip samples proven free by a checked neighbour (EdgeChecker slack=True, the
checker's free slack) give the answers of checking every sample: same free prefixes, same free /
in-collision answers, the same RRT-Connect trees and paths, with fewer checks."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.planners import EdgeChecker, RRTConfig, RRTConnect
from splatplan.planners.robot_links import LinkGeometry

from .scenes import make_checker, make_scene

robots = pytest.importorskip("splatplan.robots")

BOXES = [((0.3, -0.3, 0.0), (0.4, 0.3, 0.8)), ((-0.5, 0.2, 0.3), (-0.2, 0.5, 0.4)), ((-0.8, -0.8, -0.3), (0.8, 0.8, -0.25))]


@pytest.fixture(scope="module")
def checker():
    return make_checker(make_scene(BOXES, spacing=0.03), n_sigma=0.0)


def _arm_edges(robot, rng, e: int, scale: float, checker=None):
    lim = robot.joint_limits
    a = lim[:, 0] + rng.random((8 * e, robot.dof)) * (lim[:, 1] - lim[:, 0])
    if checker is not None:  # edges from free configurations (as the planners' are)
        a = a[~LinkGeometry(robot).collides(checker, a)]
    a = a[:e]
    b = np.clip(a + rng.normal(scale=scale, size=a.shape), lim[:, 0], lim[:, 1])
    return a, b


@pytest.mark.parametrize("stages", [1, 4])
@pytest.mark.parametrize("margin", [0.0, 0.015])
def test_arm_slack_matches_every_sample(checker, stages, margin):
    robot = robots.load_robot("panda")
    robot = robot.inflated(margin) if margin else robot
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(stages + int(1000 * margin))
    a, b = _arm_edges(robot, rng, 40, 0.6, checker)
    a[:2] = b[:2]  # zero-length edges
    res = 0.25 * robot.min_semi_axis
    ref = EdgeChecker(checker, geom, res, stages=stages)
    k_ref, n_ref = ref.free_prefix(a, b)
    q_ref = geom.n_queries
    assert 0 < (k_ref < n_ref).sum() < len(a)
    fast = EdgeChecker(checker, geom, res, stages=stages, slack=True)
    exact = rng.random(len(a)) < 0.5
    k, n = fast.free_prefix(a, b, exact=exact)
    np.testing.assert_array_equal(n, n_ref)
    np.testing.assert_array_equal(k[exact], k_ref[exact])
    np.testing.assert_array_equal(k == n, k_ref == n_ref)
    k_all, _ = fast.free_prefix(a, b)
    np.testing.assert_array_equal(k_all, k_ref)
    np.testing.assert_array_equal(fast.edges_free(a, b), k_ref == n_ref)
    if stages > 1:  # (in one call every sample is checked: nothing is known before)
        assert geom.n_queries - q_ref < 3 * q_ref  # three calls above: fewer checks than the plain one each


def test_point_robot_slack(checker):
    """A translating ellipsoid robot (no inflated inner samples): the plain motion bound per sample."""
    robot = robots.load_robot("ellipsoid:0.05,0.03,0.02")
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(2)
    a = rng.uniform(-0.6, 0.6, (60, 3)) + np.array([0.0, 0.0, 0.5])
    b = a + rng.normal(scale=0.3, size=a.shape)
    ref = EdgeChecker(checker, geom, 0.01, stages=3)
    fast = EdgeChecker(checker, geom, 0.01, stages=3, slack=True)
    k_ref, n_ref = ref.free_prefix(a, b)
    q0 = geom.n_queries
    k, n = fast.free_prefix(a, b)
    assert 0 < (k_ref < n_ref).sum() < len(a)
    np.testing.assert_array_equal(k, k_ref)
    np.testing.assert_array_equal(n, n_ref)
    assert geom.n_queries - q0 < q0


def _blocked_pair(checker, robot, seed: int):
    """A free start and goal without a straight free edge between them."""
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(seed)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((400, robot.dof)) * (lim[:, 1] - lim[:, 0])
    q = q[~geom.collides(checker, q)]
    blocked = ~EdgeChecker(checker, geom, 0.25 * robot.min_semi_axis, stages=4).edges_free(q[:-1], q[1:])
    i = int(np.nonzero(blocked)[0][0])
    return q[i], q[i + 1]


def test_rrt_connect_same_tree_and_path(checker):
    robot = robots.load_robot("panda").inflated(0.01)
    start, goal = _blocked_pair(checker, robot, 4)
    out = []
    for slack in (False, True):
        cfg = RRTConfig(seed=3, max_iters=40, time_limit_s=None, edge_slack=slack)
        out.append(RRTConnect(checker, cfg, robot=robot).plan(start, goal))
    a, b = out
    assert a.success and b.success
    np.testing.assert_array_equal(a.tree_nodes, b.tree_nodes)
    np.testing.assert_array_equal(a.path, b.path)
    assert b.info["n_queries"] < a.info["n_queries"]


def test_rrt_connect_same_tree_and_path_walked(checker):
    """RRTConfig.edge_walk: edges walked by the checker (SLACK WALK) or staged, the same search."""
    robot = robots.load_robot("panda").inflated(0.01)
    start, goal = _blocked_pair(checker, robot, 5)
    out = [RRTConnect(checker, RRTConfig(seed=3, max_iters=40, time_limit_s=None, edge_walk=w), robot=robot).plan(start, goal) for w in (False, True)]
    a, b = out
    assert a.success and b.success
    np.testing.assert_array_equal(a.tree_nodes, b.tree_nodes)
    np.testing.assert_array_equal(a.path, b.path)
    assert b.info["n_configs"] < a.info["n_configs"]
