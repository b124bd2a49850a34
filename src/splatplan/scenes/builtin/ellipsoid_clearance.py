"""Clearance of solid ellipsoids to analytic primitives (boxes, cylinders, spheres), in numpy.

``clearance(E, P) = min over points p of E of sdf_P(p)``: the Euclidean distance between the
ellipsoid and the primitive when they are apart (returned as a certified lower bound), minus the
depth of the ellipsoid's deepest point inside the primitive when they overlap. Boxes and cylinders
are solved as convex problems (alternating projections, certified by a separating plane; projected
subgradient ascent on the depth); spheres in closed form. :meth:`AnalyticScene.ellipsoid_clearance
<splatplan.scenes.builtin.analytic_scene.AnalyticScene.ellipsoid_clearance>` documents the
guarantees; :func:`ellipsoid_clearance_chunk` is its batched core.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..splats import quat_to_rotmat
from .primitive_sdf import box_sdf_local, cylinder_sdf_local

__all__ = ["ellipsoid_clearance_chunk", "fibonacci_sphere", "project_to_ellipsoid"]


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) nearly uniform unit vectors (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(np.maximum(1 - z * z, 0))
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


#: Sample directions of :func:`_ellipsoid_box` in the unit ball: 128 surface, 16 half-radius, centre.
_BALL_SAMPLES = np.concatenate([fibonacci_sphere(128), 0.5 * fibonacci_sphere(16), np.zeros((1, 3))])


def project_to_ellipsoid(y: np.ndarray, a: np.ndarray, n_newton: int = 30) -> np.ndarray:
    """Closest points (P, 3) of axis-aligned solid ellipsoids (semi-axes a (P, 3)) to points y (P, 3).

    Outside points: x_i = a_i^2 y_i / (a_i^2 + t) with t >= 0 the root of
    F(t) = sum (a_i y_i / (a_i^2 + t))^2 - 1 (convex, decreasing): Newton from t = 0 approaches it
    monotonically from below.
    """
    a2 = a * a
    inside = np.sum((y / a) ** 2, axis=1) <= 1.0
    t = np.zeros(len(y))
    ay2 = a2 * y * y
    for _ in range(n_newton):
        den = a2 + t[:, None]
        f = np.sum(ay2 / den**2, axis=1) - 1.0
        df = -2.0 * np.sum(ay2 / den**3, axis=1)
        t_new = np.maximum(t - f / np.minimum(df, -1e-300), 0.0)
        done = np.all(np.abs(t_new - t) <= 1e-15 * (a2.max(axis=1) + t))  # converged to rounding (x moves < 1e-15 relative)
        t = t_new
        if done:
            break
    x = a2 * y / (a2 + t[:, None])
    return np.where(inside[:, None], y, x)


class _BoxShape:
    """Box operations in the box frame for :func:`_ellipsoid_convex`; ``prm`` (..., 3) half-extents."""

    sdf = staticmethod(box_sdf_local)

    @staticmethod
    def project(p: np.ndarray, prm: np.ndarray) -> np.ndarray:  # (P, 3) closest points of the solid
        return np.clip(p, -prm, prm)

    @staticmethod
    def support(n: np.ndarray, prm: np.ndarray) -> np.ndarray:  # (P,) max over the solid of n.x
        return np.sum(prm * np.abs(n), axis=1)

    @staticmethod
    def size(prm: np.ndarray) -> np.ndarray:  # (P,) smallest half-size
        return prm.min(axis=1)

    @staticmethod
    def depth_step(p: np.ndarray, prm: np.ndarray, ms: np.ndarray, idx: np.ndarray):
        """(-depth (P,), inside (P,) bool, d(-depth)/du (P, 3)) at p = c + M u (a subgradient)."""
        margin = prm - np.abs(p)  # (P, 3) depth per axis
        k = np.argmin(margin, axis=1)
        g = np.sign(p[idx, k])[:, None] * ms[idx, k, :]  # d(-margin_k)/du
        return -margin[idx, k], np.all(margin >= 0, axis=1), g


class _CylinderShape:
    """Cylinder operations in the cylinder frame; ``prm`` (..., 2) = (radius, half_height), axis z."""

    sdf = staticmethod(cylinder_sdf_local)

    @staticmethod
    def project(p: np.ndarray, prm: np.ndarray) -> np.ndarray:
        rho = np.hypot(p[:, 0], p[:, 1])
        f = np.minimum(1.0, prm[:, 0] / np.maximum(rho, 1e-300))
        return np.stack([p[:, 0] * f, p[:, 1] * f, np.clip(p[:, 2], -prm[:, 1], prm[:, 1])], axis=1)

    @staticmethod
    def support(n: np.ndarray, prm: np.ndarray) -> np.ndarray:
        return prm[:, 0] * np.hypot(n[:, 0], n[:, 1]) + prm[:, 1] * np.abs(n[:, 2])

    @staticmethod
    def size(prm: np.ndarray) -> np.ndarray:
        return prm.min(axis=1)

    @staticmethod
    def depth_step(p: np.ndarray, prm: np.ndarray, ms: np.ndarray, idx: np.ndarray):
        rho = np.hypot(p[:, 0], p[:, 1])
        m_rad, m_ax = prm[:, 0] - rho, prm[:, 1] - np.abs(p[:, 2])
        radial = m_rad < m_ax
        e = np.where(rho[:, None] > 1e-300, p[:, :2] / np.maximum(rho, 1e-300)[:, None], np.array([1.0, 0.0]))  # (P, 2) radial unit
        g_rad = e[:, :1] * ms[:, 0, :] + e[:, 1:] * ms[:, 1, :]  # d(rho)/du
        g_ax = np.sign(p[:, 2])[:, None] * ms[:, 2, :]  # d|z|/du
        return -np.minimum(m_rad, m_ax), (m_rad >= 0) & (m_ax >= 0), np.where(radial[:, None], g_rad, g_ax)


def _ellipsoid_convex(
    c: np.ndarray,  # (P, 3) ellipsoid centres in the primitive's frame
    r: np.ndarray,  # (P, 3, 3) ellipsoid -> primitive frame rotations
    a: np.ndarray,  # (P, 3) semi-axes
    h: np.ndarray,  # (P, k) primitive parameters (box: half-extents; cylinder: radius, half-height)
    shape=_BoxShape,
    n_ap: int = 400,
    n_sub: int = 400,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """min over the solid ellipsoid of a convex primitive's SDF, with (lower, upper) bounds, each (P,)."""
    m = r * a[:, None, :]  # (P, 3, 3): p = c + m u, |u| <= 1
    pts = c[:, None, :] + np.einsum("pij,sj->psi", m, _BALL_SAMPLES)  # (P, S, 3)
    f = shape.sdf(pts, h[:, None, :])  # (P, S)
    best = np.argmin(f, axis=1)
    val = f[np.arange(len(c)), best]
    lower, upper = val.copy(), val.copy()
    # ---- separated (or touching): alternating projections, certified by a separating plane
    sep = val > 0
    if np.any(sep):
        cs, rs, as_, hs, ms = c[sep], r[sep], a[sep], h[sep], m[sep]
        p = pts[sep, best[sep]]  # (S', 3) start on the ellipsoid
        act = np.arange(len(p))  # pairs still moving
        for _ in range(n_ap):
            qb = shape.project(p[act], hs[act])
            y = np.einsum("pji,pj->pi", rs[act], qb - cs[act])  # ellipsoid frame
            p_new = cs[act] + np.einsum("pij,pj->pi", rs[act], project_to_ellipsoid(y, as_[act]))
            moved = np.max(np.abs(p_new - p[act]), axis=1) >= 1e-12
            p[act] = p_new
            act = act[moved]
            if len(act) == 0:
                break
        qb = shape.project(p, hs)
        diff = p - qb
        dist = np.linalg.norm(diff, axis=1)
        n = diff / np.maximum(dist, 1e-300)[:, None]
        lb = np.einsum("pi,pi->p", n, cs) - np.linalg.norm(np.einsum("pji,pj->pi", ms, n), axis=1) - shape.support(n, hs)
        ub = np.minimum(dist, val[sep])
        lower[sep] = np.minimum(np.maximum(lb, 0.0), ub)
        upper[sep] = ub
        val[sep] = lower[sep]  # the certified value: never above the true distance
    # ---- penetrating, touching, or not certified apart (no separating plane with a positive gap:
    # alternating projections between intersecting sets creep towards a common point without
    # reaching it): the deepest point by projected subgradient ascent on the depth
    pen = ~sep | (upper < 1e-9) | (lower <= 0)
    if np.any(pen):
        cs, ms, hs = c[pen], m[pen], h[pen]
        u = _BALL_SAMPLES[best[pen]].copy()  # (S', 3)
        idx = np.arange(len(u))
        best_f = shape.sdf(cs + np.einsum("pij,pj->pi", ms, u), hs)
        s0 = 0.5 * np.minimum(shape.size(hs), a[pen].min(axis=1))[:, None]  # first step (m)
        for it in range(n_sub):
            p = cs + np.einsum("pij,pj->pi", ms, u)
            fv, inside, g = shape.depth_step(p, hs, ms, idx)
            best_f = np.minimum(best_f, np.where(inside, fv, shape.sdf(p, hs)))
            gn2 = np.sum(g * g, axis=1, keepdims=True)
            u = u - s0 * (it + 1.0) ** -0.75 * g / np.maximum(gn2, 1e-300)  # the margin moves ~ the step (m)
            nu = np.linalg.norm(u, axis=1, keepdims=True)
            u = np.where(nu > 1.0, u / nu, u)
        val[pen] = np.minimum(val[pen], best_f)
        upper[pen] = val[pen]
        lower[pen] = -np.inf  # no certificate for the depth (see AnalyticScene.ellipsoid_clearance)
    return val, lower, upper


def _ellipsoid_box(c, r, a, h, n_ap: int = 400, n_sub: int = 400):
    """:func:`_ellipsoid_convex` for boxes (h (P, 3) half-extents)."""
    return _ellipsoid_convex(c, r, a, h, _BoxShape, n_ap, n_sub)


def _ellipsoid_sphere(
    c: np.ndarray,  # (P, 3) ellipsoid centres, world
    rot_e: np.ndarray,  # (P, 3, 3) ellipsoid -> world
    a: np.ndarray,  # (P, 3) semi-axes
    sph: np.ndarray,  # (P, 4) spheres (centre world, radius)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """min over the solid ellipsoid of a sphere's SDF = dist(sphere centre, ellipsoid) - radius (exact).

    ``min_{p in E} |p - s| - r``: the closest point of E to s (s itself when s is inside E, so the
    value is then exactly -r). The distance comes from the Newton projection (exact to rounding once
    converged); the lower bound is the separating plane through the projection,
    ``n.(s - c) - |diag(a) R^T n|`` with n the unit direction from the projection to s.
    """
    y = np.einsum("pji,pj->pi", rot_e, sph[:, :3] - c)  # (P, 3) sphere centre in the ellipsoid frame
    x = project_to_ellipsoid(y, a, n_newton=80)
    diff = y - x
    dist = np.linalg.norm(diff, axis=1)
    n = diff / np.maximum(dist, 1e-300)[:, None]
    lb = np.where(dist > 0, np.einsum("pi,pi->p", n, y) - np.linalg.norm(n * a, axis=1), 0.0)
    val = dist - sph[:, 3]
    return val, np.minimum(np.maximum(lb, 0.0) - sph[:, 3], val), val


def _broad_phase(scene: Any, c: np.ndarray, a: np.ndarray) -> tuple[list, np.ndarray]:
    """The primitives of ``scene`` seen from Q ellipsoid centres ``c`` (Q, 3) with semi-axes ``a``
    (Q, 3): per primitive kind (shape, local centres (Q, M, 3) or None, rotations (M, 3, 3) or None,
    params (M, k), centre SDF d_c (Q, M)), and each ellipsoid's upper bound on its clearance (Q, 1):
    d_c itself inside a primitive, max(d_c - a_min, 0) outside (the ball of radius a_min is inside E)."""
    a_min = a.min(1, keepdims=True)
    parts: list[tuple[Any, Any, Any, np.ndarray, np.ndarray]] = []
    if len(scene.boxes):
        boxes, rot_b = scene.boxes, scene.rotations()
        local = np.einsum("mji,qmj->qmi", rot_b, c[:, None, :] - boxes[None, :, :3])  # (Q, M, 3) box frame
        parts.append((_BoxShape, local, rot_b, boxes[:, 3:6], box_sdf_local(local, boxes[None, :, 3:6])))
    if len(scene.cylinders):
        cyl = scene.cylinders
        rot_c = quat_to_rotmat(cyl[:, 5:9]).reshape(-1, 3, 3)
        local = np.einsum("mji,qmj->qmi", rot_c, c[:, None, :] - cyl[None, :, :3])
        parts.append((_CylinderShape, local, rot_c, cyl[:, 3:5], cylinder_sdf_local(local, cyl[None, :, 3:5])))
    if len(scene.spheres):
        sph = scene.spheres
        parts.append((None, None, None, sph, np.linalg.norm(c[:, None, :] - sph[None, :, :3], axis=2) - sph[None, :, 3]))
    best_ub = np.full((len(c), 1), np.inf)
    for *_, d_c in parts:
        ub = np.where(d_c < 0, d_c, np.maximum(d_c - a_min, 0.0))  # min over the ellipsoid <= this
        best_ub = np.minimum(best_ub, ub.min(axis=1, keepdims=True))
    return parts, best_ub


def clearance_upper_bound(scene: Any, c: np.ndarray, a: np.ndarray) -> float:
    """An upper bound on the smallest clearance of Q ellipsoids (centres ``c`` (Q, 3), semi-axes
    ``a`` (Q, 3)) to ``scene``, from their centres alone (:func:`_broad_phase`; +inf for none)."""
    return float(_broad_phase(scene, c, a)[1].min()) if len(c) else float("inf")


def ellipsoid_clearance_chunk(
    scene: Any,  # an AnalyticScene (boxes, cylinders, spheres rows)
    c: np.ndarray,  # (Q, 3) world
    rot_e: np.ndarray,  # (Q, 3, 3) ellipsoid -> world
    a: np.ndarray,  # (Q, 3)
    cutoff: float = float("inf"),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value, lower, upper) (Q,) of the clearance of Q ellipsoids to every primitive of ``scene``.

    Broad phase over all primitives (:func:`_broad_phase`): the SDF of the ellipsoid's centre d_c
    gives an upper bound and the lower bound d_c - a_max (the SDF is 1-Lipschitz); only pairs whose
    lower bound reaches the best upper bound over every primitive are solved. ``cutoff``: pairs
    whose lower bound exceeds it are not solved either (an ellipsoid with none left reads +inf: its
    clearance exceeds ``cutoff``)."""
    q_n = len(c)
    a_max = a.max(1, keepdims=True)
    parts, best_ub = _broad_phase(scene, c, a)
    best_ub = np.minimum(best_ub, cutoff)
    out, out_lo, out_hi = np.full(q_n, np.inf), np.full(q_n, np.inf), np.full(q_n, np.inf)
    for shape, local, rot_p, prm, d_c in parts:
        cand_q, cand_m = np.nonzero(d_c - a_max <= best_ub + 1e-12)  # 1-Lipschitz lower bound can reach the best
        if len(cand_q) == 0:
            continue
        if shape is None:  # spheres: closed form
            val, lo, hi = _ellipsoid_sphere(c[cand_q], rot_e[cand_q], a[cand_q], prm[cand_m])
        else:
            r_loc = np.einsum("pji,pjk->pik", rot_p[cand_m], rot_e[cand_q])  # (P, 3, 3) ellipsoid -> primitive frame
            val, lo, hi = _ellipsoid_convex(local[cand_q, cand_m], r_loc, a[cand_q], prm[cand_m], shape)
        np.minimum.at(out, cand_q, val)
        np.minimum.at(out_lo, cand_q, lo)
        np.minimum.at(out_hi, cand_q, hi)
    return out, out_lo, out_hi
