"""Planes in a capture, for :mod:`splatplan.scenes.align`: a shell-robust box of the splat means,
a one-point RANSAC over the flat splats (:func:`fit_planes`), how much of the scene lies over a plane
(:func:`support_coverage`), and the rotation that takes a plane's normal to +z.

Units: the capture's; frame: the file's as loaded. Normals are unit (3,) vectors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .splats import Splats

__all__ = ["Plane", "describe_plane", "fit_planes", "nearest_axis", "robust_box", "rotation_to_z", "shell_weights", "support_coverage"]


@dataclass
class Plane:
    """A fitted plane n . x = d (input frame), its share of the robust splat mass, and how one-sided the scene is."""

    normal: np.ndarray  # (3,) unit, oriented towards the bulk of the scene
    offset: float  # d, input units
    mass: float  # opacity-weighted inlier share of the robust subset
    one_sided: float  # share of the robust mass not beyond the plane (1 = everything on the normal's side)
    n_inliers: int
    inliers: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0, np.int64))  # indices into the fit subset
    coverage: float = 0.0  # share of the off-plane mass projecting inside the inliers' convex hull (see support_coverage)


def nearest_axis(v: np.ndarray) -> str:
    """'+x'..'-z': the signed coordinate axis nearest to ``v`` (3,)."""
    i = int(np.argmax(np.abs(v)))
    return ("+" if v[i] >= 0 else "-") + "xyz"[i]


def robust_box(means: np.ndarray, percentile: float = 1.0, pad: float = 0.1, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lo (3,), hi (3,), inside (N,) bool): the per-axis weighted percentile box of ``means``
    (N, 3), padded by ``pad`` of its size per side; ``inside`` marks the means in it (the rest: a
    shell or far outliers). ``weights`` (N,) default 1; :func:`shell_weights` makes a shell of
    many huge splats count little even when it holds a large share of the splats."""
    m = np.asarray(means, np.float64)
    w = np.ones(len(m)) if weights is None else np.asarray(weights, np.float64)
    lo, hi = np.empty(3), np.empty(3)
    for k in range(3):
        o = np.argsort(m[:, k])
        cw = np.cumsum(w[o])
        cw /= cw[-1]
        i_lo = min(int(np.searchsorted(cw, percentile / 100.0)), len(o) - 1)
        i_hi = min(int(np.searchsorted(cw, 1.0 - percentile / 100.0)), len(o) - 1)
        lo[k], hi[k] = m[o[i_lo], k], m[o[i_hi], k]
    size = hi - lo
    lo, hi = lo - pad * size, hi + pad * size
    inside = np.all((m >= lo) & (m <= hi), axis=1)
    return lo, hi, inside


def shell_weights(splats: Splats) -> np.ndarray:
    """(N,) weights of the robust box: opacity / max(largest std, median largest std)^2, so a sky
    shell or a cloud of huge floaters (large stds) hardly moves the box's percentiles while the
    scene's surfaces (small, opaque splats) define it."""
    smax = splats.scales.max(axis=1).astype(np.float64)
    ref = max(float(np.median(smax)), 1e-12)
    return splats.opacities.astype(np.float64) / np.maximum(smax, ref) ** 2 + 1e-12


def fit_planes(means, normals, flat, weights, tol: float, n_planes: int = 6, n_hypotheses: int = 800, seed: int = 0) -> list[Plane]:
    """Sequential one-point RANSAC (see the module docstring, step 2).

    Args:
        means: (M, 3) input frame. normals: (M, 3) unit. flat: (M,) bool. weights: (M,) >= 0.
        tol: inlier distance (input units).

    Returns:
        up to ``n_planes`` planes, in the order found; ``normal`` points to the side holding most
        of the weight and ``one_sided`` is that side's share (inliers counted on both sides).
    """
    rng = np.random.default_rng(seed)
    m = np.asarray(means, np.float64)
    w = np.asarray(weights, np.float64)
    total = max(float(w.sum()), 1e-12)
    cos_agree = np.cos(np.radians(25.0))
    alive = np.ones(len(m), bool)
    out: list[Plane] = []
    for _ in range(n_planes):
        cand = np.flatnonzero(alive & flat)
        if len(cand) < 10:
            break
        h = rng.choice(cand, min(n_hypotheses, len(cand)), replace=False)
        n = normals[h]  # (H, 3)
        d = np.einsum("hi,hi->h", n, m[h])  # (H,)
        idx = np.flatnonzero(alive)
        best_score, best = -1.0, None
        for lo in range(0, len(h), 200):  # chunks of hypotheses: (A, 200) matrices
            nn, dd = n[lo : lo + 200], d[lo : lo + 200]
            inl = (np.abs(m[idx] @ nn.T - dd) < tol) & ((np.abs(normals[idx] @ nn.T) > cos_agree) | ~flat[idx, None])
            score = w[idx] @ inl
            b = int(np.argmax(score))
            if score[b] > best_score:
                best_score, best = float(score[b]), idx[inl[:, b]]
        if best is None or len(best) < 3:
            break
        wi = w[best] + 1e-12
        c = np.average(m[best], axis=0, weights=wi)
        _, _, vt = np.linalg.svd((m[best] - c) * np.sqrt(wi)[:, None], full_matrices=False)
        nrm = vt[2] / np.linalg.norm(vt[2])
        off = float(nrm @ c)
        side = m @ nrm - off  # (M,) all robust means
        above = float(w[side > tol].sum()) / total
        below = float(w[side < -tol].sum()) / total
        if below > above:
            nrm, off, above, below = -nrm, -off, below, above
        out.append(Plane(nrm, off, best_score / total, 1.0 - below, len(best), best))
        alive[best] = False
    return out


def rotation_to_z(up: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking the unit vector ``up`` to +z (about x for up = -z)."""
    u = np.asarray(up, np.float64) / np.linalg.norm(up)
    z = np.array([0.0, 0.0, 1.0])
    c = float(u @ z)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    v = np.cross(u, z)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def support_coverage(means: np.ndarray, weights: np.ndarray, plane: Plane, tol: float, max_hull_points: int = 20000) -> float:
    """Share of the off-plane weight whose projection onto ``plane`` falls inside the convex hull
    of the plane's inliers (grown by 5% about its centroid): 1 for a floor or a table disc under
    an object (the hidden patch under the object included), low for a chair's back (the seat and
    legs hang beyond it). ``means`` (M, 3) and ``weights`` (M,) are the fit subset of
    :func:`fit_planes` (input frame); off-plane = farther than ``3 tol`` from the plane. 0 when
    the inliers span no area."""
    from scipy.spatial import ConvexHull, Delaunay, QhullError

    n = np.asarray(plane.normal, np.float64)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    uv = np.asarray(means, np.float64) @ np.stack([a, b], axis=1)  # (M, 2) in-plane coordinates
    inl = plane.inliers
    if len(inl) > max_hull_points:
        inl = inl[np.linspace(0, len(inl) - 1, max_hull_points).astype(np.int64)]
    pts = uv[inl]
    try:
        hull = pts[ConvexHull(pts).vertices]
        c = hull.mean(axis=0)
        tri = Delaunay(c + 1.05 * (hull - c))
    except (QhullError, ValueError):  # collinear or too few inliers: no area
        return 0.0
    off = np.abs(np.asarray(means, np.float64) @ n - plane.offset) > 3.0 * tol
    w = np.asarray(weights, np.float64)[off]
    if w.sum() <= 0:
        return 1.0
    inside = tri.find_simplex(uv[off]) >= 0
    return float(w[inside].sum() / w.sum())


def describe_plane(p: Plane) -> str:
    """One line for messages: the plane's normal, its share of the mass and its coverage."""
    return f"normal {nearest_axis(p.normal)} {np.round(p.normal, 2).tolist()}, {p.mass:.0%} of the mass, coverage {p.coverage:.0%}"
