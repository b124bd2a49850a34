"""Splat-Nav K-test against exact sphere-ellipsoid overlap computed independently."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.optimize import minimize

from splatplan.baselines.splatnav import SplatNav, max_k_torch, splatnav_score

# Near-tangent margin: we only require agreement when the sphere-surface distance differs from r
# by more than 1e-4 r. (Observed: no disagreement beyond 3e-8 r on 20k samples; the bisected
# max_t K is never above the true max, so errors can only flag tangent contacts as collisions.)
MARGIN = 1e-4


def _per_pair_maxk(sn: SplatNav, centers: np.ndarray, radius: float) -> np.ndarray:
    """max_t K of query i against Gaussian i (pairs, not the min over the scene)."""
    c = torch.as_tensor(centers, dtype=sn.scene.dtype)
    v = torch.einsum("nij,nj->ni", sn.rot_t, sn.scene.means - c)
    return max_k_torch((v * v)[None], sn.lam, radius**2)[0].numpy()


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_k_test_matches_exact_overlap_near_tangency(make_scene, dtype):
    # Exact construction: for a point on the ellipsoid surface x_s with outward unit normal n, the
    # point x_s + L n (L >= 0) has distance exactly L to the (convex) ellipsoid. Overlap iff L <= r.
    sc = make_scene(4000, seed=3, smin=0.002, smax=0.2)
    rng = np.random.default_rng(4)
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    xs = u * sc["scales"]  # on the 1-sigma surface, principal frame
    nrm = xs / sc["scales"] ** 2
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    r = 0.03
    rel = np.concatenate([rng.uniform(-0.5, 0.5, 2000), rng.uniform(-1e-3, 1e-3, 2000)])
    dist = r * (1 + rel)
    centers = sc["means"] + np.einsum("nij,nj->ni", sc["rot"], xs + nrm * dist[:, None])
    sn = SplatNav(sc, dtype=dtype)
    kmax = _per_pair_maxk(sn, centers, r)
    ok = np.abs(rel) > MARGIN
    assert ok.sum() > 3000
    np.testing.assert_array_equal(kmax[ok] < 1, dist[ok] <= r)


def _min_mahalanobis_in_ball(y: np.ndarray, e: np.ndarray, r: float) -> float:
    """min over |x - y| <= r of sum (x/e)^2 (convex, SLSQP). <= 1 iff sphere and ellipsoid overlap."""
    if np.linalg.norm(y) <= r:
        return 0.0
    cons = {"type": "ineq", "fun": lambda x: r * r - np.sum((x - y) ** 2), "jac": lambda x: -2 * (x - y)}
    res = minimize(lambda x: np.sum((x / e) ** 2), y - r * y / np.linalg.norm(y), jac=lambda x: 2 * x / e**2,
                   constraints=[cons], method="SLSQP", options={"ftol": 1e-14, "maxiter": 500})
    return float(res.fun)


def test_scene_score_matches_constrained_minimisation(make_scene):
    sc = make_scene(10, seed=7)
    rng = np.random.default_rng(8)
    centers = sc["means"][rng.integers(0, 10, 100)] + rng.normal(size=(100, 3)) * 0.06
    r = 0.02
    m = np.array([[_min_mahalanobis_in_ball(sc["rot"][i].T @ (c - sc["means"][i]), sc["scales"][i], r)
                   for i in range(10)] for c in centers])  # [B, N]
    truth = (m <= 1).any(axis=1)
    near = (np.abs(m - 1) < 1e-3).any(axis=1)
    score = splatnav_score(sc, centers, r)
    assert truth.sum() > 10 and (~truth).sum() > 10
    np.testing.assert_array_equal((score < 1)[~near], truth[~near])


def test_level_equals_scaled_splats(make_scene):
    sc = make_scene(50, seed=1)
    c = np.random.default_rng(0).normal(size=(20, 3)) * 0.15
    scaled = dict(sc, scales=sc["scales"] * np.sqrt(2.5))
    a = SplatNav(sc, level=2.5, dtype=torch.float64).score(c, 0.02)
    b = SplatNav(scaled, dtype=torch.float64).score(c, 0.02)
    np.testing.assert_allclose(a, b, rtol=1e-12)


def test_batch_gives_identical_values(make_scene):
    sc = make_scene(40, seed=2)
    c = np.random.default_rng(1).normal(size=(17, 3)) * 0.15
    sn = SplatNav(sc)
    np.testing.assert_array_equal(sn.score(c, 0.02), sn.score(c, 0.02, batch=5))


def test_analytic_sphere_on_axis():
    # Ellipsoid semi-axes (0.2, 0.1, 0.05) at the origin; a sphere r = 0.1 on the x axis at
    # distance x touches at x = 0.3 and K_max = x^2 / (0.2 + 0.1)^2 there.
    sc = {"means": np.zeros((1, 3)), "quats": np.array([[1.0, 0, 0, 0]]), "scales": np.array([[0.2, 0.1, 0.05]])}
    x = np.array([0.1, 0.2, 0.29, 0.31, 0.4])
    c = np.stack([x, 0 * x, 0 * x], axis=1)
    s = SplatNav(sc, dtype=torch.float64).score(c, 0.1)
    np.testing.assert_allclose(s, x**2 / 0.09, rtol=1e-6)
