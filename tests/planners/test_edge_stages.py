"""The coarse-to-fine edge check (EdgeChecker stages > 1) against the one-call reference
(stages = 1: every check sample in one call): same free prefixes, same free / in-collision answers,
for an arm (joint-space edges), a translating sphere (inflated inner samples) and every stage count."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners import RRT, EdgeChecker, edge_samples
from splatplan.planners.edges import shortcut_path
from splatplan.planners.robot_links import LinkGeometry

from .scenes import make_checker, make_scene, wall_scene

robots = pytest.importorskip("splatplan.robots")


@pytest.fixture(scope="module")
def panda_boxes():
    boxes = [((0.3, -0.3, 0.0), (0.4, 0.3, 0.8)), ((-0.5, 0.2, 0.3), (-0.2, 0.5, 0.4))]
    return make_checker(make_scene(boxes, spacing=0.03), n_sigma=1.0)


def _arm_edges(robot, rng, e: int, scale: float):
    lim = robot.joint_limits
    a = lim[:, 0] + rng.random((e, 7)) * (lim[:, 1] - lim[:, 0])
    b = np.clip(a + rng.normal(scale=scale, size=a.shape), lim[:, 0], lim[:, 1])
    return a, b


@pytest.mark.parametrize("stages", [2, 3, 5])
def test_arm_stages_match_one_call(panda_boxes, stages):
    robot = robots.load_robot("panda")
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(stages)
    a, b = _arm_edges(robot, rng, 24, 0.5)
    a[:3] = b[:3]  # zero-length edges: one sample each
    res = 0.25 * robot.min_semi_axis
    ref = EdgeChecker(panda_boxes, geom, res, stages=1)
    fast = EdgeChecker(panda_boxes, geom, res, stages=stages)
    k_ref, n_ref = ref.free_prefix(a, b)
    q_ref = ref.n_queries
    assert 0 < (k_ref < n_ref).sum() < len(a)  # both kinds of edge
    exact = rng.random(len(a)) < 0.5
    k, n = fast.free_prefix(a, b, exact=exact)
    q_fast = fast.n_queries - q_ref
    np.testing.assert_array_equal(n, n_ref)
    np.testing.assert_array_equal(k[exact], k_ref[exact])  # exact prefixes where asked
    np.testing.assert_array_equal(k == n, k_ref == n_ref)  # free or not everywhere
    assert np.all(k[~exact] <= n[~exact])
    hit_pts, _, _ = edge_samples(a, b, geom.motion(b - a), res)
    first = np.cumsum(n) - n
    for e in np.nonzero(~exact & (k < n))[0]:  # a reported hit is a real one
        assert geom.collides(panda_boxes, hit_pts[first[e] + k[e]][None])[0]
    np.testing.assert_array_equal(fast.edges_free(a, b), k_ref == n_ref)
    assert q_fast < q_ref  # it saved checks here (the geometry's counter is shared)


def test_sphere_inflated_stages_match_one_call():
    ch = make_checker(wall_scene(), n_sigma=0.0)
    rrt = RRT(ch, robot="sphere:0.015")
    rng = np.random.default_rng(1)
    a = np.column_stack([rng.uniform(-0.25, 0.25, 40), rng.uniform(-0.3, 0.3, 40), np.full(40, 0.06)])
    b = a + np.column_stack([rng.normal(scale=0.15, size=(40, 2)), np.zeros(40)])
    ref = EdgeChecker(ch, rrt.geometry, 0.004, inflate=True, stages=1)
    fast = EdgeChecker(ch, rrt.geometry, 0.004, inflate=True, stages=3)
    k_ref, n_ref = ref.free_prefix(a, b)
    assert 0 < (k_ref < n_ref).sum() < len(a)
    k, n = fast.free_prefix(a, b)
    np.testing.assert_array_equal(k, k_ref)
    np.testing.assert_array_equal(n, n_ref)
    np.testing.assert_array_equal(fast.edges_free(a, b), k_ref == n_ref)
    assert fast.path_free(a[:1]) == ref.path_free(a[:1])


def test_empty_and_bad_stages(panda_boxes):
    geom = LinkGeometry(robots.load_robot("panda"))
    k, n = EdgeChecker(panda_boxes, geom, 0.01, stages=3).free_prefix(np.zeros((0, 7)), np.zeros((0, 7)))
    assert k.shape == n.shape == (0,)
    with pytest.raises(SplatplanError):
        EdgeChecker(panda_boxes, geom, 0.01, stages=0)


def test_arm_walk_matches_one_call(panda_boxes):
    """``walk``: edges_free by the checker's SLACK WALK, the one-call answers with fewer checks."""
    robot = robots.load_robot("panda")
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(7)
    a, b = _arm_edges(robot, rng, 24, 0.5)
    a[:3] = b[:3]
    res = 0.25 * robot.min_semi_axis
    ref = EdgeChecker(panda_boxes, geom, res, stages=1)
    k_ref, n_ref = ref.free_prefix(a, b)
    assert 0 < (k_ref < n_ref).sum() < len(a)
    walk = EdgeChecker(panda_boxes, geom, res, stages=4, slack=True, walk=True)
    c0 = geom.n_configs
    np.testing.assert_array_equal(walk.edges_free(a, b), k_ref == n_ref)
    assert 0 < geom.n_configs - c0 < n_ref.sum()  # counted, and fewer than every sample
    assert walk.edges_free(a[:0], b[:0]).shape == (0,)


@pytest.mark.parametrize("screen", [None, 4])
def test_shortcut_with_the_walk_is_the_same_path(panda_boxes, screen):
    """shortcut_path (doubling candidates, screened or not) keeps the same vertices whether its
    edges are walked (each candidate one walk with its screen, farthest first) or staged."""
    robot = robots.load_robot("panda")
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(3)
    lim = robot.joint_limits
    steps = np.clip(np.cumsum(rng.normal(scale=0.25, size=(400, 7)), axis=0), lim[:, 0], lim[:, 1])  # a random walk in joint space
    path = steps[~np.asarray(panda_boxes.collides_configs(robot, steps))][:14]  # its free configurations
    assert len(path) >= 10
    res = 0.25 * robot.min_semi_axis
    walk = EdgeChecker(panda_boxes, geom, res, stages=4, slack=True, walk=True)
    staged = EdgeChecker(panda_boxes, geom, res, stages=1)
    assert walk.walks and not staged.walks
    got = shortcut_path(walk, path, candidates="doubling", screen=screen)
    want = shortcut_path(staged, path, candidates="doubling", screen=screen)
    np.testing.assert_array_equal(got, want)
    assert len(got) < len(path)
