"""Zeroth-order refinement: never returns a colliding path, shortens zig-zags, keeps endpoints."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.planners import RRT, EdgeChecker, RefineConfig, RRTConfig, path_length, refine_path, smoothness
from splatplan.robots import load_robot

from .scenes import make_checker, wall_scene

R = 0.015
SPHERE = load_robot(f"sphere:{R}")
PLANE = dict(box_lo=(-0.25, -0.3, 0.06), box_hi=(0.25, 0.3, 0.06))


@pytest.fixture(scope="module")
def checker():
    return make_checker(wall_scene(), n_sigma=1.0)


def _free(checker, path):
    return EdgeChecker(checker, RRT(checker, robot=SPHERE).geometry, R / 2).path_free(path)


def test_shortens_zigzag(checker):
    # a collision-free zig-zag on the free side of the wall (x < -0.05)
    y = np.linspace(-0.2, 0.2, 9)
    x = -0.15 + 0.04 * (np.arange(9) % 2)
    zig = np.stack([x, y, np.full(9, 0.06)], axis=1)
    assert _free(checker, zig)
    out = refine_path(checker, zig, robot=SPHERE, config=RefineConfig(seed=0))
    assert out.accepted, out.message
    np.testing.assert_allclose(out.path[0], zig[0], atol=1e-12)
    np.testing.assert_allclose(out.path[-1], zig[-1], atol=1e-12)
    assert path_length(out.path) < 0.95 * path_length(zig)
    assert smoothness(out.path) < 0.5 * smoothness(zig)
    np.testing.assert_allclose(out.path[:, 2], 0.06)  # a planar path stays planar
    assert out.cost_after < out.cost_before
    assert _free(checker, out.path)


@pytest.mark.parametrize("seed", range(4))
def test_never_returns_colliding_path(checker, seed):
    rrt = RRT(checker, RRTConfig(seed=seed, shortcut=seed % 2 == 0, **PLANE), robot=SPHERE).plan((-0.15, 0.0, 0.06), (0.15, 0.0, 0.06))
    assert rrt.success
    # normal settings and deliberately bad ones (huge noise, very few knots, greedy temperature)
    for cfg in (RefineConfig(seed=seed), RefineConfig(seed=seed, n_knots=4, noise_sigma=0.1, temperature=1e-4, max_attempts=1)):
        out = refine_path(checker, rrt.path, robot=SPHERE, config=cfg)
        assert _free(checker, out.path), out.message
        if not out.accepted:
            np.testing.assert_array_equal(out.path, rrt.path)


def test_rejects_when_no_free_curve_exists(checker):
    # a path whose corners hug the wall's end: a 4-knot spline cuts the corner through the wall
    path = np.array([[-0.15, 0.0, 0.06], [-0.03, 0.15, 0.06], [0.03, 0.15, 0.06], [0.15, 0.0, 0.06]])
    assert _free(checker, path)
    cfg = RefineConfig(n_knots=4, noise_sigma=1e-6, max_attempts=1, w_collision=0.0, w_hit=0.0)
    out = refine_path(checker, path, robot=SPHERE, config=cfg)
    assert not out.accepted and "kept the original" in out.message
    np.testing.assert_array_equal(out.path, path)


def test_defaults_scale_with_the_robot(checker):
    y = np.linspace(-0.2, 0.2, 9)
    zig = np.stack([-0.15 + 0.04 * (np.arange(9) % 2), y, np.full(9, 0.06)], axis=1)
    for r in (0.015, 0.01):
        out = refine_path(checker, zig, robot=load_robot(f"sphere:{r}"), config=RefineConfig(seed=0))
        assert out.info["knot_spacing"] == pytest.approx(r * 20 / 3)
        assert out.info["noise_sigma"] == pytest.approx(0.8 * r) and out.info["temperature"] == pytest.approx(r / 3)
