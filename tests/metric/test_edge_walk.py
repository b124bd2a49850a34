"""The SLACK WALK of straight configuration-space edges (:meth:`CollisionChecker.edges_free`,
:mod:`splatplan.metric.edge_walk`): the kernel (one thread per edge) against the same walk from
Python (:func:`walk_with_checker`: the same answers and the same number of checks) and against checking
every sample (the answer it stands for), on random and near-surface edges in every n_sigma regime;
a robot that does not move needs one check; a batch past the launcher's capacity; the reference
backend; invalid input."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.edge_walk import walk_with_checker
from splatplan.metric.wp_metric import TierConfig

from .conftest import random_scene

robots = pytest.importorskip("splatplan.robots")


def _setup(n_sigma: float, seed: int, backend: str = "warp"):
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, 4000, scale=0.005 / (1.0 + n_sigma))
    scene.means[:] = rng.uniform(-1.0, 1.0, (4000, 3)) * np.array([0.03, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])  # a slab the arm reaches
    ch = CollisionChecker(scene, config=MetricConfig(n_sigma=n_sigma), device="cpu", backend=backend, tiers=TierConfig(distance_grid_voxels=2**15))
    robot = robots.load_robot("panda").inflated(0.01)
    return ch, robot, rng


def _edges(ch, robot, rng, n_edges: int, scale: float):
    """Edges from free configurations (half of them near a colliding one), their sample counts
    at 5 mm and each ellipsoid's step (its motion bound over the edge, over n)."""
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((40 * n_edges, robot.dof)) * (lim[:, 1] - lim[:, 0])
    hit = np.asarray(ch.collides_configs(robot, q))
    near = q[hit][rng.integers(0, int(hit.sum()), 8 * n_edges)] + rng.normal(scale=0.15, size=(8 * n_edges, robot.dof))
    starts = np.concatenate([q[~hit][: n_edges // 2], near[np.asarray(ch.collides_configs(robot, near)) == 0][: n_edges // 2]])
    ends = starts + rng.normal(scale=scale, size=starts.shape)
    motion = np.abs(ends - starts) @ robot.motion_bound
    n = np.maximum(1, np.ceil(motion / 0.005)).astype(np.int64)
    step = (np.abs(ends - starts) @ robot.ellipsoid_motion_bounds().T) / n[:, None]
    return starts, ends, n, step


def _every_sample_free(ch, robot, starts, ends, n) -> np.ndarray:
    out = []
    for a, b, k in zip(starts, ends, n):
        pts = a + (np.arange(1, k + 1) / k)[:, None] * (b - a)
        out.append(not np.asarray(ch.collides_configs(robot, pts)).any())
    return np.asarray(out)


def _python_walk(ch, robot, starts, ends, n, step, t, screen=0):
    return walk_with_checker(ch, robot, starts, ends, n, step, t, screen)


@pytest.mark.parametrize("n_sigma", [0.0, 1.0, 3.0])
def test_kernel_walk_is_the_python_walk_and_every_sample(n_sigma):
    ch, robot, rng = _setup(n_sigma, seed=int(n_sigma) + 3)
    starts, ends, n, step = _edges(ch, robot, rng, 40, 0.3)
    want = _every_sample_free(ch, robot, starts, ends, n)
    assert 0 < want.sum() < len(want)  # both kinds of edge
    for t, screen in ((1, 0), (4, 0), (4, 8)):
        free, checks = ch.edges_free(robot, starts, ends, n, step, target_steps=t, screen=screen)
        ref_free, ref_checks = _python_walk(ch, robot, starts, ends, n, step, t, screen)
        np.testing.assert_array_equal(free, want)
        np.testing.assert_array_equal(free, ref_free)
        np.testing.assert_array_equal(checks, ref_checks)
        assert checks.dtype == np.int64 and (checks >= 1).all() and (checks <= n + (n // screen if screen else 0)).all()
    free, checks = ch.edges_free(robot, starts, ends, n, step)
    assert checks[free].sum() < 0.5 * n[free].sum()  # the slack skipped samples
    _, screened = ch.edges_free(robot, starts, ends, n, step, screen=4)
    assert screened[~free].sum() < checks[~free].sum()  # the screen found the hits sooner


def test_near_surface_edges_and_a_long_batch():
    """Edges that graze the slab (short hops around near-surface configurations), 300 of them in
    one call (past the launcher's first capacity): the answers of checking every sample."""
    ch, robot, rng = _setup(0.0, seed=11)
    starts, ends, n, step = _edges(ch, robot, rng, 300, 0.05)
    assert len(starts) > 256
    free, checks = ch.edges_free(robot, starts, ends, n, step)
    np.testing.assert_array_equal(free, _every_sample_free(ch, robot, starts, ends, n))
    ref_free, ref_checks = _python_walk(ch, robot, starts, ends, n, step, 4)
    np.testing.assert_array_equal(checks, ref_checks)
    assert 0 < free.sum() < len(free)


def test_no_motion_needs_one_check():
    ch, robot, rng = _setup(0.0, seed=5)
    starts, ends, n, step = _edges(ch, robot, rng, 10, 0.3)
    free, checks = ch.edges_free(robot, starts, ends, n, np.zeros_like(step))  # (a claim: nothing moves)
    assert (checks == 1).all()
    k = np.minimum(n, 5)  # the first sample checked: target_steps (4) past the start
    first = starts + (k / n)[:, None] * (ends - starts)
    np.testing.assert_array_equal(free, ~np.asarray(ch.collides_configs(robot, first)))


def test_reference_backend_walks_every_sample():
    ch, robot, rng = _setup(1.0, seed=2)
    ref = CollisionChecker(ch.scene, config=MetricConfig(n_sigma=1.0), backend="reference")
    starts, ends, n, step = _edges(ch, robot, rng, 6, 0.1)
    free, checks = ref.edges_free(robot, starts, ends, n, step)
    np.testing.assert_array_equal(free, ch.edges_free(robot, starts, ends, n, step)[0])
    assert (checks[free] == n[free]).all()  # (no slack from the reference: every sample checked)


def test_empty_and_invalid_input():
    ch, robot, rng = _setup(0.0, seed=1)
    free, checks = ch.edges_free(robot, np.zeros((0, 7)), np.zeros((0, 7)), np.zeros(0, dtype=int), np.zeros((0, robot.n_ellipsoids)))
    assert free.shape == checks.shape == (0,)
    a = np.zeros((2, 7))
    st = np.zeros((2, robot.n_ellipsoids))
    n = np.array([3, 4])
    for args, what in [
        ((np.zeros((2, 6)), a, n, st), "shape"),
        ((a, np.full((2, 7), np.nan), n, st), "finite"),
        ((a, a, np.array([0, 4]), st), "n_samples"),
        ((a, a, np.array([3.5, 4]), st), "whole"),
        ((a, a, n, st[:, :3]), "step"),
        ((a, a, n, -np.ones_like(st)), ">= 0"),
    ]:
        with pytest.raises(SplatplanError, match=what):
            ch.edges_free(robot, *args)
    with pytest.raises(SplatplanError, match="target_steps"):
        ch.edges_free(robot, a, a, n, st, target_steps=0)
    with pytest.raises(SplatplanError, match="screen"):
        ch.edges_free(robot, a, a, n, st, screen=-1)


def test_validate_false_checks_shapes_only():
    ch, robot, rng = _setup(0.0, seed=4)
    starts, ends, n, step = _edges(ch, robot, rng, 8, 0.2)
    np.testing.assert_array_equal(ch.edges_free(robot, starts, ends, n, step, validate=False)[0], ch.edges_free(robot, starts, ends, n, step)[0])
    with pytest.raises(SplatplanError, match="shape"):
        ch.edges_free(robot, starts, ends, n[:3], step, validate=False)
