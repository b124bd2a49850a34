"""Path metrics: length, d_min to splat means, smoothness, clearance."""

from __future__ import annotations

import numpy as np

from splatplan.planners.metrics import SMOOTHNESS_POINTS, clearance, d_min, densify_path, path_length, smoothness


def test_length_and_densify():
    p = np.array([[0, 0, 0], [0.3, 0, 0], [0.3, 0.4, 0]], float)
    assert abs(path_length(p) - 0.7) < 1e-12
    d = densify_path(p, 0.01)
    assert np.linalg.norm(np.diff(d, axis=0), axis=1).max() <= 0.01 + 1e-12
    np.testing.assert_allclose(d[[0, -1]], p[[0, -1]])


def test_d_min_matches_brute_force():
    rng = np.random.default_rng(0)
    means = rng.uniform(-0.5, 0.5, (500, 3))
    p = np.array([[-0.4, -0.4, 0.0], [0.4, 0.3, 0.1]])
    dense = densify_path(p, 0.0005)
    brute = np.linalg.norm(dense[:, None] - means[None], axis=-1).min()
    assert abs(d_min(p, means, spacing=0.0005) - brute) < 1e-12
    assert abs(d_min(p, means) - brute) < 1e-3  # default spacing 0.002


def test_smoothness_definition():
    line = np.linspace([0, 0, 0], [1, 1, 0], 5)
    assert smoothness(line) < 1e-20
    # a right-angle corner exactly on a sample (101 points, corner at half length -> sample 50)
    # contributes 4 sin^2(45 deg) = 2 once, averaged over the M - 2 = 99 interior samples
    corner = np.array([[0, 0, 0], [0.5, 0, 0], [0.5, 0.5, 0]])
    s = smoothness(corner, n_points=101)
    assert abs(s - 2.0 / 99) < 1e-9
    # scale and translation invariant
    assert abs(smoothness(corner * 7 + 3, n_points=101) - s) < 1e-9
    # a circle arc of total turning phi: S ~ (phi / (M - 1))^2
    t = np.linspace(0, np.pi / 2, 400)
    arc = np.stack([np.cos(t), np.sin(t), 0 * t], 1)
    assert abs(smoothness(arc) - (np.pi / 2 / (SMOOTHNESS_POINTS - 1)) ** 2) < 1e-5


def test_clearance_with_analytic_sdf():
    sdf = lambda x: np.linalg.norm(x, axis=-1) - 0.1  # noqa: E731  a ball of radius 0.1 at the origin
    p = np.array([[-0.5, 0.2, 0.0], [0.5, 0.2, 0.0]])
    assert abs(clearance(p, sdf, radius=0.015) - (0.2 - 0.1 - 0.015)) < 1e-6
    assert clearance(np.array([[-0.5, 0.05, 0.0], [0.5, 0.05, 0.0]]), sdf, 0.015) < 0
