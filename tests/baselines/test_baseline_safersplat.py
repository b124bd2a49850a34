"""SAFER-Splat point-to-ellipsoid distance against an independent float64 root solve (brentq)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.optimize import brentq

from splatplan.baselines.safersplat import SaferSplat, ellipsoid_distance_torch, safersplat_score


def _distance_brentq(y: np.ndarray, e: np.ndarray) -> tuple[float, bool]:
    """Distance from y to the ellipsoid sum (x/e)^2 = 1 via brentq on the unnormalised equation.

    G(T) = sum (e_i y_i / (T + e_i^2))^2 - 1, closest point x_i = e_i^2 y_i / (T + e_i^2);
    root in (0, |e * y|] outside, in (-min e^2, 0) inside (non-degenerate case y_k != 0).
    """
    g = lambda t: np.sum((e * y / (t + e**2)) ** 2) - 1.0
    inside = np.sum((y / e) ** 2) < 1
    if inside:
        lo = -np.min(e) ** 2
        t = brentq(g, lo * (1 - 1e-15), 0.0, xtol=1e-300, rtol=1e-15, maxiter=1000)
    else:
        t = brentq(g, 0.0, np.linalg.norm(e * y) + 1e-300, xtol=1e-300, rtol=1e-15, maxiter=1000)
    x = e**2 * y / (t + e**2)
    return float(np.linalg.norm(x - y)), bool(inside)


def _pairs(sc, centers, dtype):
    sa = SaferSplat(sc, dtype=dtype)
    c = torch.as_tensor(centers, dtype=dtype)
    y = torch.einsum("nij,nj->ni", sa.rot_t, c - sa.scene.means)  # per pair: query i vs Gaussian i
    d, inside = ellipsoid_distance_torch(y[None], sa.semi_axes)
    return d[0].numpy(), inside[0].numpy()


# 25 bisection steps bound the accuracy: observed max relative error ~6e-6 outside (wide
# brackets for far points on elongated splats), ~1e-11 inside in float64, ~2e-5 in float32.
@pytest.mark.parametrize("dtype,rtol", [(torch.float64, 3e-5), (torch.float32, 1e-4)])
def test_distance_matches_brentq_inside_and_outside(make_scene, dtype, rtol):
    n = 600
    sc = make_scene(n, seed=11, smin=0.003, smax=0.1)
    rng = np.random.default_rng(12)
    # Half the queries inside (scaled unit-ball points), half outside at varied distances.
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    radial = np.concatenate([rng.uniform(0.05, 0.95, n // 2), rng.uniform(1.05, 20.0, n // 2)])
    y = u * radial[:, None] * sc["scales"]
    centers = sc["means"] + np.einsum("nij,nj->ni", sc["rot"], y)
    ref = np.array([_distance_brentq(y[i], sc["scales"][i]) for i in range(n)], dtype=object)
    d_ref = ref[:, 0].astype(float)
    in_ref = ref[:, 1].astype(bool)
    d, inside = _pairs(sc, centers, dtype)
    np.testing.assert_array_equal(inside, in_ref)
    assert in_ref.sum() == n // 2
    # Tolerance relative to the distance, plus an absolute floor at float precision of the scene.
    atol = 1e-12 if dtype == torch.float64 else 1e-7
    np.testing.assert_allclose(d, d_ref, rtol=rtol, atol=atol)


def test_exact_outside_distance_along_normals(make_scene):
    # x_s + L n (n the outward normal at the surface point x_s) is at distance exactly L.
    n = 500
    sc = make_scene(n, seed=5, smin=0.001, smax=0.2)
    rng = np.random.default_rng(6)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    xs = u * sc["scales"]
    nrm = xs / sc["scales"] ** 2
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    L = rng.uniform(1e-3, 0.5, n)
    centers = sc["means"] + np.einsum("nij,nj->ni", sc["rot"], xs + nrm * L[:, None])
    d, inside = _pairs(sc, centers, torch.float32)
    assert not inside.any()
    np.testing.assert_allclose(d, L, rtol=2e-5)


def test_degenerate_inside_points():
    # Centre exactly at the mean: distance = smallest semi-axis. On the plane y_k = 0 inside:
    # Eberly's degenerate solution x_i = e_i^2 y_i / (e_i^2 - e_k^2) (i != k), x_k from the surface.
    e = np.array([0.3, 0.2, 0.1])
    sc = {"means": np.zeros((1, 3)), "quats": np.array([[1.0, 0, 0, 0]]), "scales": e[None]}
    sa = SaferSplat(sc, dtype=torch.float64)
    ys = np.array([[0.0, 0.0, 0.0], [0.05, 0.03, 0.0], [-0.1, 0.0, 0.0]])
    for y in ys:
        with np.errstate(invalid="ignore"):
            x = e**2 * y / (e**2 - e[2] ** 2)  # x[2] is 0/0 here and set next
        x[2] = e[2] * np.sqrt(1 - np.sum((x[:2] / e[:2]) ** 2))
        d_ref = np.linalg.norm(x - y)
        d, inside = ellipsoid_distance_torch(torch.as_tensor(y)[None, None], sa.semi_axes)
        assert bool(inside[0, 0])
        assert abs(float(d[0, 0]) - d_ref) < 1e-9, (y, float(d[0, 0]), d_ref)
        h = sa.score(y[None], 0.01)[0]
        assert abs(h - (-(d_ref**2) - 0.01**2)) < 1e-9


def test_barrier_sign_and_2dgs_disks(make_scene):
    sc = make_scene(30, seed=9)
    sc["scales"][:, 2] = 0.0  # 2DGS disks
    c = np.random.default_rng(2).normal(size=(40, 3)) * 0.15
    h = safersplat_score(sc, c, 0.02, batch=8)
    assert np.isfinite(h).all()
    np.testing.assert_array_equal(h, safersplat_score(sc, c, 0.02))
