"""Ellipsoid maths of the link models: volume, the Mahalanobis radius (inside test), the
minimum-volume enclosing ellipsoid (Khachiyan), the volume of a union, points on the surface.

An ellipsoid is (centre c (3,), rotation R (3, 3) frame <- ellipsoid frame, semi-axes s (3,)). A
point x lies inside when ``|diag(1/s) R^T (x - c)| <= 1``.

A leaf of the robot stage: the fitters (:mod:`~splatplan.robots.fit`,
:mod:`~splatplan.robots.fit_cover`, :mod:`~splatplan.robots.fit_opt`) and the measurement
(:mod:`~splatplan.robots.fit_measure`) all read it; it reads none of them.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SplatplanError

__all__ = ["CONTAIN_EPS", "ellipsoid_volume", "mahalanobis", "mvee", "sphere_points", "surface_of", "union_volume"]

#: Relative safety factor applied after the exact containment rescale (float rounding).
CONTAIN_EPS = 1e-9


def ellipsoid_volume(semi_axes: np.ndarray) -> np.ndarray:
    return 4.0 / 3.0 * math.pi * np.prod(np.asarray(semi_axes, dtype=np.float64), axis=-1)


def mahalanobis(points: np.ndarray, center: np.ndarray, rot: np.ndarray, semi_axes: np.ndarray) -> np.ndarray:
    """|diag(1/s) R^T (p - c)| for points (N, 3): <= 1 inside."""
    local = (np.asarray(points, dtype=np.float64) - center) @ rot  # (N, 3) ellipsoid frame
    return np.linalg.norm(local / semi_axes, axis=-1)


def _hull_vertices(points: np.ndarray) -> np.ndarray:
    from scipy.spatial import ConvexHull, QhullError

    if len(points) <= 4:
        return points
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def mvee(points: np.ndarray, tol: float = 1e-3, max_iter: int = 20000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-volume enclosing ellipsoid of points (N, 3) by Khachiyan's algorithm.

    Returns (centre (3,), rotation (3, 3) with det +1, semi-axes (3,) descending). The result
    contains every point (rescaled by the largest Mahalanobis radius); flat or tiny point sets
    get a thickness of 1e-3 of their extent (at least 1e-6 m).
    """
    p = np.unique(np.asarray(points, dtype=np.float64).reshape(-1, 3), axis=0)
    if len(p) == 0 or not np.all(np.isfinite(p)):
        raise SplatplanError("cannot fit an ellipsoid to an empty or non-finite point set")
    mean = p.mean(axis=0)
    a = p - mean
    a = np.linalg.qr(a, mode="r") if len(a) >= 3 else np.vstack([a, np.zeros((3 - len(a), 3))])  # (3, 3), same singular values
    _, sv, vt = np.linalg.svd(a, full_matrices=False)  # vt (3, 3); no (N, N) factor for large N
    extent = max(float(np.ptp(p, axis=0).max()), 1e-6)
    pad = max(1e-3 * extent, 1e-6)
    extra = []
    for i in range(3):  # give flat / line / point sets a small thickness
        if sv[i] <= 1e-9 * max(sv[0], 1e-300):
            extra += [mean + pad * vt[i], mean - pad * vt[i]]
    if extra:
        p = np.concatenate([p, np.array(extra)])
    p = _hull_vertices(p)
    n, d = p.shape
    qm = np.vstack([p.T, np.ones(n)])  # (4, N) lifted points
    u = np.full(n, 1.0 / n)
    for _ in range(max_iter):
        x = (qm * u) @ qm.T  # (4, 4)
        m = np.einsum("in,ij,jn->n", qm, np.linalg.inv(x), qm)
        j = int(np.argmax(m))
        mj = m[j]
        if mj <= (1.0 + tol) * (d + 1):
            break
        step = (mj - d - 1.0) / ((d + 1.0) * (mj - 1.0))
        u *= 1.0 - step
        u[j] += step
    c = p.T @ u
    cov = (p.T * u) @ p - np.outer(c, c)
    a = np.linalg.inv(cov) / d  # (x - c)^T A (x - c) <= 1 (approximately)
    lam, vec = np.linalg.eigh(0.5 * (a + a.T))  # ascending eigenvalues -> descending semi-axes
    lam = np.maximum(lam, 1e-30)
    s = 1.0 / np.sqrt(lam)
    if np.linalg.det(vec) < 0:
        vec[:, 2] *= -1.0
    r = float(mahalanobis(p, c, vec, s).max())
    s = s * r * (1.0 + CONTAIN_EPS)
    return c, vec, s


def union_volume(ells: list, n: int = 200_000, seed: int = 0) -> float:
    """Volume of the union of ellipsoids [(c, R, s), ...]: exact for one (or disjoint bounding
    boxes), otherwise Monte Carlo over their joint bounding box (n samples, fixed seed, ~0.5%)."""
    if len(ells) == 1:
        return float(ellipsoid_volume(ells[0][2]))
    half = [np.abs(r) @ s for _, r, s in ells]  # axis-aligned half extents
    lo = np.min([c - h for (c, _, _), h in zip(ells, half)], axis=0)
    hi = np.max([c + h for (c, _, _), h in zip(ells, half)], axis=0)
    pts = np.random.default_rng(seed).uniform(lo, hi, size=(n, 3))
    inside = np.zeros(n, dtype=bool)
    for c, r, s in ells:
        inside |= mahalanobis(pts, c, r, s) <= 1.0
    return float(inside.mean() * np.prod(hi - lo))


def sphere_points(n: int) -> np.ndarray:
    """(n, 3) nearly uniform unit vectors (Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def surface_of(e: tuple, dirs: np.ndarray) -> np.ndarray:
    """Points c + R diag(s) u on an ellipsoid's surface for unit vectors u (N, 3)."""
    c, r, s = e
    return c + (dirs * s) @ r.T
