"""Analytic scenes: unions of oriented boxes with an exact signed distance.

A built-in scene (see :mod:`.stonehenge`) is a set of solid oriented boxes. The boxes are the
*ground truth* geometry: splats are sampled from their surfaces, and evaluation studies use
:meth:`AnalyticScene.sdf` to decide whether a query point is in collision
(``sdf(p) < r`` for a sphere robot of radius ``r``).

Units and frames
----------------
* Coordinates are in *scene units* in the scene's world frame (z up for the built-in scenes).
* A box row is ``(cx, cy, cz, hx, hy, hz, qw, qx, qy, qz)``: centre (world), half-extents along
  the box's own x/y/z axes, and a **wxyz** unit quaternion rotating the box frame into the world
  frame (``p_world = R @ p_box + c``).

Exactness of the signed distance of a union
-------------------------------------------
Each box has an exact signed distance ``d_i`` (negative inside). For the union we return
``min_i d_i``:

* **outside** the union (all ``d_i >= 0``) this is the exact Euclidean distance to the union,
  because the distance to a union of sets is the minimum of the distances to the sets;
* **inside** the union it is negative (the sign is right) but its magnitude may be *smaller* than
  the true depth when boxes overlap (the nearest face of the containing box may be buried in
  another box): ``min_i d_i >= true_sdf``.

So ``sdf(p) < r`` (for ``r >= 0``) is the exact ground-truth collision test for a sphere of radius
``r`` centred at ``p``, which is what the studies need.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..._config import bounded, check_config
from ...errors import SplatplanError
from ..splats import Splats, quat_multiply, quat_to_rotmat

__all__ = ["AnalyticScene", "SurfaceSplatConfig", "box_corners", "box_sdf", "make_box", "splats_from_boxes"]

#: Format tag written into JSON files produced by :meth:`AnalyticScene.to_json`.
JSON_FORMAT = "splatplan.analytic_scene"
JSON_VERSION = 1


def make_box(
    center,  # (3,) world
    half_extents,  # (3,) box frame
    quat=(1.0, 0.0, 0.0, 0.0),  # (4,) wxyz, box -> world
) -> np.ndarray:
    """One box row ``(c, h, q)`` as float64 (10,), with the quaternion normalised (w >= 0)."""
    q = np.asarray(quat, dtype=np.float64)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-12:
        raise SplatplanError(f"make_box: quaternion {quat!r} is zero or not finite")
    q = q / n
    if q[0] < 0:
        q = -q
    return np.concatenate([np.asarray(center, np.float64), np.asarray(half_extents, np.float64), q])


def _yaw_quat(yaw: float) -> np.ndarray:
    """wxyz (4,) rotation by ``yaw`` (rad) about +z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _copy_splats(s: Splats) -> Splats:
    """Fresh arrays of a cached built-in scene's splats (``info`` copied too)."""
    return replace(
        s,
        means=s.means.copy(),
        quats=s.quats.copy(),
        scales=s.scales.copy(),
        opacities=s.opacities.copy(),
        colors=s.colors.copy(),
        info=dict(s.info),
    )


def box_sdf(
    points: np.ndarray,  # (P, 3) world
    box: np.ndarray,  # (10,) c, h, q(wxyz)
) -> np.ndarray:
    """Exact signed distance (P,) float64 from ``points`` to one solid box (negative inside).

    This is the slow, obviously-correct single-box reference used by the tests.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    c, h, q = box[:3], box[3:6], box[6:10]
    rot = quat_to_rotmat(q)  # (3, 3) box -> world
    local = (p - c) @ rot  # (P, 3) = R^T (p - c)
    d = np.abs(local) - h  # (P, 3)
    outside = np.linalg.norm(np.maximum(d, 0.0), axis=1)
    inside = np.minimum(d.max(axis=1), 0.0)
    return outside + inside


def box_corners(box: np.ndarray) -> np.ndarray:
    """The 8 world-frame corners of a box, float64 (8, 3) (index bits: x, y, z sign)."""
    signs = np.array([[(i >> 0) & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], np.float64) * 2 - 1
    rot = quat_to_rotmat(box[6:10])
    return (signs * box[3:6]) @ rot.T + box[:3]


def _sdf_dense(
    p: np.ndarray,  # (P, 3) float64
    boxes: np.ndarray,  # (M, 10)
    rot: np.ndarray,  # (M, 3, 3) box -> world
    chunk: int | None = None,
) -> np.ndarray:
    """min over the boxes of the exact box SDFs, (P,) float64, by brute force in chunks."""
    m = boxes.shape[0]
    out = np.empty(p.shape[0])
    if chunk is None:
        chunk = max(256, int(1_000_000 // (3 * m)))
    # Box-frame coordinates of every point for every box in one GEMM:
    # R_m^T (p - c_m) = p @ R_m - c_m @ R_m, stacked as p @ W - b with W (3, 3M), b (3M,).
    w = rot.transpose(1, 0, 2).reshape(3, 3 * m)
    b = np.einsum("mi,mij->mj", boxes[:, :3], rot).reshape(3 * m)
    h = boxes[:, 3:6][None]  # (1, M, 3)
    for s in range(0, p.shape[0], chunk):
        local = (p[s : s + chunk] @ w - b).reshape(-1, m, 3)  # (C, M, 3) box-frame coordinates
        np.abs(local, out=local)
        local -= h
        inside = np.minimum(local.max(axis=2), 0.0)  # (C, M)
        np.maximum(local, 0.0, out=local)
        outside = np.sqrt(np.einsum("cmi,cmi->cm", local, local))
        out[s : s + chunk] = (outside + inside).min(axis=1)
    return out


def _fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) nearly uniform unit vectors (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(np.maximum(1 - z * z, 0))
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


#: Sample directions of :func:`_ellipsoid_box` in the unit ball: 128 surface, 16 half-radius, centre.
_BALL_SAMPLES = np.concatenate([_fibonacci_sphere(128), 0.5 * _fibonacci_sphere(16), np.zeros((1, 3))])


def _project_ellipsoid(y: np.ndarray, a: np.ndarray, n_newton: int = 30) -> np.ndarray:
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
        t = np.maximum(t - f / np.minimum(df, -1e-300), 0.0)
    x = a2 * y / (a2 + t[:, None])
    return np.where(inside[:, None], y, x)


def _box_sdf_local(p: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Box SDF for points p (..., 3) in the box frame, half-extents h broadcast (..., 3)."""
    d = np.abs(p) - h
    return np.linalg.norm(np.maximum(d, 0.0), axis=-1) + np.minimum(d.max(axis=-1), 0.0)


def _ellipsoid_box(
    c: np.ndarray,  # (P, 3) ellipsoid centres in the box frame
    r: np.ndarray,  # (P, 3, 3) ellipsoid -> box frame rotations
    a: np.ndarray,  # (P, 3) semi-axes
    h: np.ndarray,  # (P, 3) box half-extents
    n_ap: int = 400,
    n_sub: int = 400,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """min over the solid ellipsoid of the box SDF, with (lower, upper) bounds, each (P,)."""
    m = r * a[:, None, :]  # (P, 3, 3): p = c + m u, |u| <= 1
    pts = c[:, None, :] + np.einsum("pij,sj->psi", m, _BALL_SAMPLES)  # (P, S, 3)
    f = _box_sdf_local(pts, h[:, None, :])  # (P, S)
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
            qb = np.clip(p[act], -hs[act], hs[act])
            y = np.einsum("pji,pj->pi", rs[act], qb - cs[act])  # ellipsoid frame
            p_new = cs[act] + np.einsum("pij,pj->pi", rs[act], _project_ellipsoid(y, as_[act]))
            moved = np.max(np.abs(p_new - p[act]), axis=1) >= 1e-12
            p[act] = p_new
            act = act[moved]
            if len(act) == 0:
                break
        qb = np.clip(p, -hs, hs)
        diff = p - qb
        dist = np.linalg.norm(diff, axis=1)
        n = diff / np.maximum(dist, 1e-300)[:, None]
        lb = np.einsum("pi,pi->p", n, cs) - np.linalg.norm(np.einsum("pji,pj->pi", ms, n), axis=1) - np.sum(hs * np.abs(n), axis=1)
        ub = np.minimum(dist, val[sep])
        lower[sep] = np.minimum(np.maximum(lb, 0.0), ub)
        upper[sep] = ub
        val[sep] = ub
    # ---- penetrating (or touching): the deepest point by projected subgradient ascent on the depth
    pen = ~sep | (upper < 1e-9)
    if np.any(pen):
        cs, ms, hs = c[pen], m[pen], h[pen]
        u = _BALL_SAMPLES[best[pen]].copy()  # (S', 3)
        idx = np.arange(len(u))
        best_f = _box_sdf_local(cs + np.einsum("pij,pj->pi", ms, u), hs)
        s0 = 0.5 * np.minimum(hs.min(axis=1), a[pen].min(axis=1))[:, None]  # first step (m)
        for it in range(n_sub):
            p = cs + np.einsum("pij,pj->pi", ms, u)
            margin = hs - np.abs(p)  # (S', 3) depth per axis
            k = np.argmin(margin, axis=1)
            fv = -margin[idx, k]
            best_f = np.minimum(best_f, np.where(np.all(margin >= 0, axis=1), fv, _box_sdf_local(p, hs)))
            g = np.sign(p[idx, k])[:, None] * ms[idx, k, :]  # d(-margin_k)/du
            gn2 = np.sum(g * g, axis=1, keepdims=True)
            u = u - s0 * (it + 1.0) ** -0.75 * g / np.maximum(gn2, 1e-300)  # the margin moves ~ the step (m)
            nu = np.linalg.norm(u, axis=1, keepdims=True)
            u = np.where(nu > 1.0, u / nu, u)
        val[pen] = np.minimum(val[pen], best_f)
        upper[pen] = val[pen]
        lower[pen] = -np.inf  # no certificate for the depth (see AnalyticScene.ellipsoid_clearance)
    return val, lower, upper


def _ellipsoid_clearance_chunk(
    boxes: np.ndarray,  # (M, 10)
    rot_b: np.ndarray,  # (M, 3, 3) box -> world
    c: np.ndarray,  # (Q, 3) world
    rot_e: np.ndarray,  # (Q, 3, 3) ellipsoid -> world
    a: np.ndarray,  # (Q, 3)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    q_n = len(c)
    local = np.einsum("mji,qmj->qmi", rot_b, c[:, None, :] - boxes[None, :, :3])  # (Q, M, 3) box frame
    d_c = _box_sdf_local(local, boxes[None, :, 3:6])  # (Q, M) SDF of the centre per box
    a_max, a_min = a.max(1, keepdims=True), a.min(1, keepdims=True)
    ub = np.where(d_c < 0, d_c, np.maximum(d_c - a_min, 0.0))  # min over the ellipsoid <= this
    lb = d_c - a_max  # 1-Lipschitz: >= this
    cand_q, cand_m = np.nonzero(lb <= ub.min(axis=1, keepdims=True) + 1e-12)
    r_loc = np.einsum("pji,pjk->pik", rot_b[cand_m], rot_e[cand_q])  # (P, 3, 3) ellipsoid -> box frame
    val, lo, hi = _ellipsoid_box(local[cand_q, cand_m], r_loc, a[cand_q], boxes[cand_m, 3:6])
    out, out_lo, out_hi = np.full(q_n, np.inf), np.full(q_n, np.inf), np.full(q_n, np.inf)
    np.minimum.at(out, cand_q, val)
    np.minimum.at(out_lo, cand_q, lo)
    np.minimum.at(out_hi, cand_q, hi)
    return out, out_lo, out_hi


@dataclass
class AnalyticScene:
    """A union of solid oriented boxes with an exact signed distance (see module docstring).

    Attributes:
        boxes: float64 (M, 10) rows ``(cx, cy, cz, hx, hy, hz, qw, qx, qy, qz)``; centre in the
            world frame (scene units), half-extents in the box frame, wxyz unit quaternion
            rotating the box frame into the world frame.
        labels: M short names, one per box (e.g. "ground", "sarsen", "lintel"); free-form.
        meta: free-form JSON-serialisable metadata (units, robot radius, generator, ...).
    """

    boxes: np.ndarray
    labels: list[str] = field(default_factory=list)
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        b = np.asarray(self.boxes, dtype=np.float64)
        if b.ndim == 1 and b.size == 0:
            b = b.reshape(0, 10)
        if b.ndim != 2 or b.shape[1] != 10:
            raise SplatplanError(f"AnalyticScene.boxes has shape {b.shape}, expected (M, 10)")
        if not np.all(np.isfinite(b)):
            raise SplatplanError("AnalyticScene.boxes contains NaN/Inf")
        if np.any(b[:, 3:6] <= 0):
            raise SplatplanError("AnalyticScene.boxes: half-extents must be > 0")
        qn = np.linalg.norm(b[:, 6:10], axis=1)
        if np.any(qn < 1e-12):
            raise SplatplanError("AnalyticScene.boxes: zero quaternion")
        b[:, 6:10] /= qn[:, None]
        self.boxes = np.ascontiguousarray(b)
        if not self.labels:
            self.labels = ["box"] * len(b)
        self.labels = [str(s) for s in self.labels]
        if len(self.labels) != len(b):
            raise SplatplanError(f"AnalyticScene: {len(self.labels)} labels for {len(b)} boxes")

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    # ------------------------------------------------------------------ geometry
    @property
    def _rot(self) -> np.ndarray:
        """(M, 3, 3) box -> world rotations (recomputed, so edits to ``boxes`` are honoured)."""
        return quat_to_rotmat(self.boxes[:, 6:10]).reshape(-1, 3, 3)

    def rotations(self) -> np.ndarray:
        """float64 (M, 3, 3) box-to-world rotation matrices."""
        return self._rot

    def sdf(
        self,
        points: np.ndarray,  # (P, 3) or (3,)
        *,
        chunk: int | None = None,
        box_ids: np.ndarray | None = None,
        broad_phase: bool = True,
    ) -> np.ndarray:
        """Signed distance (P,) float64 from points to the union of boxes (negative inside).

        Exact outside the union; inside, ``min`` of the box distances (right sign, magnitude may be
        too small where boxes overlap; see the module docstring). Memory is bounded: points are
        processed in chunks so that temporaries stay around ``chunk * M * 3`` float64 values.

        The broad phase bins the points into cells and evaluates, per cell, only the boxes that can
        hold the minimum (AABB lower bound <= the cell's best upper bound ``max |corner - c_m|``);
        it changes nothing in the result, only the speed.

        Args:
            points: (P, 3) or (3,) world coordinates, scene units.
            chunk: points per chunk; default keeps each temporary below ~8 MB.
            box_ids: optional subset of box indices to take the union over (default: all).
            broad_phase: cull boxes per cell of points (exact; off = brute force over all boxes).

        Returns:
            float64 (P,) signed distances (scene units); a (3,) input gives a (1,) result.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        boxes = self.boxes if box_ids is None else self.boxes[box_ids]
        rot = quat_to_rotmat(boxes[:, 6:10]).reshape(-1, 3, 3)
        m = boxes.shape[0]
        if m == 0 or p.shape[0] == 0:
            return np.full(p.shape[0], np.inf)
        if not broad_phase or p.shape[0] < 4096 or m < 8:
            return _sdf_dense(p, boxes, rot, chunk)
        out = np.empty(p.shape[0])
        half = np.einsum("mij,mj->mi", np.abs(rot), boxes[:, 3:6])
        b_lo, b_hi = boxes[:, :3] - half, boxes[:, :3] + half  # (M, 3) box AABBs
        p_lo, p_hi = p.min(0), p.max(0)
        n_cells = np.clip(np.ceil((p_hi - p_lo) / (np.max(p_hi - p_lo) / 8 + 1e-300)), 1, 8).astype(int)
        size = np.maximum((p_hi - p_lo) / n_cells, 1e-12)
        cell = np.minimum(((p - p_lo) / size).astype(int), n_cells - 1)  # (P, 3)
        key = (cell[:, 0] * n_cells[1] + cell[:, 1]) * n_cells[2] + cell[:, 2]
        order = np.argsort(key, kind="stable")
        uniq, starts = np.unique(key[order], return_index=True)
        ends = np.append(starts[1:], len(order))
        corner_sign = np.array([[(i >> 0) & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], np.float64)
        for k, s0, s1 in zip(uniq, starts, ends):
            idx = order[s0:s1]
            c_lo, c_hi = p[idx].min(0), p[idx].max(0)  # tight AABB of this cell's points
            corners = c_lo + corner_sign * (c_hi - c_lo)  # (8, 3)
            # upper bound for every point of the cell: dist to the box centre (inside the box)
            upper = np.linalg.norm(corners[:, None, :] - boxes[None, :, :3], axis=2).max(0).min()
            gap = np.maximum(np.maximum(b_lo - c_hi, c_lo - b_hi), 0.0)  # (M, 3)
            cand = np.flatnonzero(np.linalg.norm(gap, axis=1) <= upper)
            out[idx] = _sdf_dense(p[idx], boxes[cand], rot[cand], chunk)
        return out

    def ellipsoid_clearance(
        self,
        centers: np.ndarray,  # (..., 3) world
        quats: np.ndarray | None,  # (..., 4) wxyz ellipsoid -> world, or None (axis-aligned)
        semi_axes: np.ndarray,  # (3,) or (..., 3) in the ellipsoid frame
        *,
        return_bounds: bool = False,
        chunk: int = 4096,
    ):
        """Smallest signed distance from each solid ellipsoid to the union of boxes, (...,) float64.

        ``clearance(E) = min over points p of E of sdf(p) = min_i min_{p in E} d_i(p)``:

        * positive: the exact Euclidean distance between the ellipsoid and the nearest box;
        * negative: minus the depth of the ellipsoid's deepest point inside a box (the right sign;
          for overlapping boxes the depth inside one box, see the module docstring).

        Each ellipsoid-box problem is convex (the box SDF is convex, the ellipsoid is convex). The
        positive case is solved by alternating projections between the ellipsoid and the box from
        the best of 145 surface/interior samples; it returns the length of the final closest-pair
        candidate (an upper bound) and certifies it with a separating-plane lower bound
        ``n.c - |M^T n| - sum_k h_k |n_k|`` (``return_bounds`` gives both; their gap is < 1e-7 m in
        the tests). The negative case maximises ``min_k (h_k - |p_k|)`` over the ellipsoid by
        projected subgradient ascent (300 steps) from the best sample; the depth it finds is a
        feasible point's depth, so it is a lower bound on the true depth (tests: within 0.1 mm).
        A broad phase skips boxes whose lower bound ``d_i(c) - a_max`` exceeds the best upper bound.

        Args:
            centers: ellipsoid centres, world frame, scene units.
            quats: wxyz rotations ellipsoid -> world (None: axis-aligned).
            semi_axes: semi-axes along the ellipsoid's own axes (broadcast over the batch).
            return_bounds: also return (lower, upper) bounds (...,) on the clearance.
            chunk: ellipsoids per batch (memory ~ chunk * M floats).

        Returns:
            (...,) float64 clearances, or (clearance, lower, upper) with ``return_bounds``.
        """
        c = np.asarray(centers, dtype=np.float64)
        if c.shape[-1:] != (3,):
            raise SplatplanError(f"ellipsoid_clearance: centers must be (..., 3), got {c.shape}")
        shape = c.shape[:-1]
        c = c.reshape(-1, 3)
        q = np.broadcast_to(np.array([1.0, 0, 0, 0]), shape + (4,)) if quats is None else np.broadcast_to(np.asarray(quats, np.float64), shape + (4,))
        a = np.broadcast_to(np.asarray(semi_axes, np.float64), shape + (3,)).reshape(-1, 3)
        q = q.reshape(-1, 4)
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(q)) and np.all(np.isfinite(a))):
            raise SplatplanError("ellipsoid_clearance: NaN or Inf in the ellipsoids")
        if np.any(a <= 0):
            raise SplatplanError("ellipsoid_clearance: semi-axes must be > 0")
        out = np.full(len(c), np.inf)
        lo_b, hi_b = np.full(len(c), np.inf), np.full(len(c), np.inf)
        if len(self) and len(c):
            rot_e = quat_to_rotmat(q / np.linalg.norm(q, axis=1, keepdims=True)).reshape(-1, 3, 3)
            for s in range(0, len(c), chunk):
                sl = slice(s, s + chunk)
                out[sl], lo_b[sl], hi_b[sl] = _ellipsoid_clearance_chunk(self.boxes, self._rot, c[sl], rot_e[sl], a[sl])
        if return_bounds:
            return out.reshape(shape), lo_b.reshape(shape), hi_b.reshape(shape)
        return out.reshape(shape)

    def sdf_gradient(self, points: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        """Central-difference gradient (P, 3) of :meth:`sdf` (unit length almost everywhere)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        g = np.empty_like(p)
        for k in range(3):
            e = np.zeros(3)
            e[k] = eps
            g[:, k] = (self.sdf(p + e) - self.sdf(p - e)) / (2 * eps)
        return g

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World-frame axis-aligned bounds (min, max) of all boxes, each float64 (3,)."""
        if len(self) == 0:
            raise SplatplanError("the analytic scene has no boxes")
        # |R| h gives the half-size of the AABB of a rotated box.
        half = np.einsum("mij,mj->mi", np.abs(self._rot), self.boxes[:, 3:6])
        return (self.boxes[:, :3] - half).min(0), (self.boxes[:, :3] + half).max(0)

    def corners(self) -> np.ndarray:
        """float64 (M, 8, 3) world corners of every box."""
        return np.stack([box_corners(b) for b in self.boxes]) if len(self) else np.zeros((0, 8, 3))

    def select(self, mask_or_idx) -> "AnalyticScene":
        """A new scene with the chosen boxes (boolean mask or index array)."""
        idx = np.arange(len(self))[mask_or_idx]
        return AnalyticScene(self.boxes[idx].copy(), [self.labels[i] for i in idx], dict(self.meta))

    # ------------------------------------------------------------------ serialisation
    def to_json(self) -> dict:
        """A JSON-serialisable dict (float64 values kept with full precision)."""
        return {
            "format": JSON_FORMAT,
            "version": JSON_VERSION,
            "box_layout": "cx cy cz hx hy hz qw qx qy qz (half-extents in the box frame; wxyz box->world)",
            "boxes": self.boxes.tolist(),
            "labels": list(self.labels),
            "meta": self.meta,
        }

    @classmethod
    def from_json(cls, d: dict) -> "AnalyticScene":
        """Inverse of :meth:`to_json`; raises :class:`SplatplanError` on a malformed dict."""
        if not isinstance(d, dict) or d.get("format") != JSON_FORMAT:
            raise SplatplanError(f"not an analytic scene JSON (expected 'format': '{JSON_FORMAT}')")
        if int(d.get("version", -1)) > JSON_VERSION:
            raise SplatplanError(f"analytic scene JSON version {d.get('version')} is newer than supported ({JSON_VERSION})")
        try:
            boxes = np.asarray(d["boxes"], dtype=np.float64).reshape(-1, 10)
        except (KeyError, ValueError, TypeError) as e:
            raise SplatplanError(f"analytic scene JSON: bad 'boxes' field ({e})") from e
        return cls(boxes, list(d.get("labels", [])), dict(d.get("meta", {})))

    def save(self, path) -> Path:
        """Write :meth:`to_json` to ``path`` (UTF-8 JSON). Returns the path."""
        path = Path(path)
        path.write_text(json.dumps(self.to_json(), indent=1))
        return path

    @classmethod
    def load(cls, path) -> "AnalyticScene":
        """Read a file written by :meth:`save`."""
        path = Path(path)
        if not path.is_file():
            raise SplatplanError(f"analytic scene file not found: {path}")
        try:
            d = json.loads(path.read_text())
        except json.JSONDecodeError as e:
            raise SplatplanError(f"{path}: not valid JSON ({e})") from e
        return cls.from_json(d)


# ---------------------------------------------------------------------------------------------
# Box surfaces -> 3DGS-like splats
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SurfaceSplatConfig:
    """How :func:`splats_from_boxes` turns box surfaces into 3DGS-like splats.

    All lengths are relative to the *local sample spacing* ``h`` (the side of the jittered-grid cell
    a splat was drawn from), so the look is the same at any splat count.
    """

    #: Tangential std = ``tangential_factor * h`` before jitter (0.5-0.7 makes neighbours overlap).
    tangential_factor: float = bounded(0.6, gt=0)
    #: Normal std = ``thickness * smaller tangential std`` (flat splats: 0.1-0.2).
    thickness: float = bounded(0.15, gt=0)
    #: Log-std of the per-splat isotropic size jitter (lognormal).
    size_jitter: float = bounded(0.25, ge=0)
    #: Log-std of the in-plane anisotropy: s_t1 = s exp(+a), s_t2 = s exp(-a), a ~ N(0, this)
    #: clipped at 2 std.
    anisotropy: float = bounded(0.15, ge=0)
    #: Log-std of the jitter of the normal std (the normal std stays below the tangential ones).
    thickness_jitter: float = bounded(0.3, ge=0)
    #: Std (degrees) of the tilt of a splat's normal axis away from the face normal (0 = exact).
    tilt_deg: float = 0.0
    #: Position noise along the face normal, std = this * h.
    normal_noise: float = bounded(0.15, ge=0)
    #: Position noise in the face plane, std = this * h.
    tangential_noise: float = bounded(0.2, ge=0)
    #: Fraction of splats with a lower opacity drawn from U(low_opacity_range).
    low_opacity_fraction: float = bounded(0.15, ge=0, le=1)
    #: Opacity range of the low-opacity splats.
    low_opacity_range: tuple[float, float] = bounded((0.15, 0.6), ge=0, le=1)
    #: The others get 1 - (1 - min_high_opacity) * U^2 (mostly close to 1).
    min_high_opacity: float = bounded(0.6, ge=0, le=1)
    #: Per-splat colour noise std (RGB, added to the box's base colour, then clipped to [0, 1]).
    color_noise: float = bounded(0.04, ge=0)
    #: Fraction of all splats that are floaters (large, transparent, in free space).
    floater_fraction: float = bounded(0.0005, ge=0, le=1)
    #: Floater max std = U(range) * median over surface splats of their max std.
    floater_size_range: tuple[float, float] = bounded((8.0, 25.0), gt=0)
    #: Fraction of floaters with opacity < 0.1 (the rest get U(0.1, 0.3): a filter misses them).
    floater_transparent_fraction: float = bounded(0.85, ge=0, le=1)
    #: Floaters are kept at least this far (scene units) from the geometry.
    floater_clearance: float = bounded(0.02, ge=0)

    def validate(self) -> "SurfaceSplatConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)


#: Face ids: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z (in the box frame).
FACE_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")


def _face_frames(box: np.ndarray, rot: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per face of one box: (centre (3,), frame (3, 3) columns t1 t2 n (right-handed), half (2,))."""
    out = []
    h = box[3:6]
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3
        for sign in (1.0, -1.0):
            n = sign * rot[:, k]
            if sign > 0:
                t1, t2, ha, hb = rot[:, a], rot[:, b], h[a], h[b]
            else:  # swap the tangents so that (t1, t2, n) stays right-handed
                t1, t2, ha, hb = rot[:, b], rot[:, a], h[b], h[a]
            out.append((box[:3] + n * h[k], np.stack([t1, t2, n], axis=1), np.array([ha, hb])))
    return out


def _sample_faces(
    scene: AnalyticScene,
    spacing: np.ndarray,  # (M,) target grid spacing per box
    faces: np.ndarray,  # (M, 6) bool, which faces to sample
    rng: np.random.Generator,
) -> dict[str, np.ndarray]:
    """Jittered-grid samples on the chosen faces, with buried samples removed.

    Returns a dict of arrays over the kept samples S: ``p`` (S, 3) points, ``frame`` (S,) face index
    into ``face_rot``/``face_box``, ``h`` (S,) local spacing (sqrt of the cell area), plus the
    per-face ``face_rot`` (F, 3, 3) and ``face_box`` (F,) arrays.
    """
    rots = scene.rotations()
    pts, fid, hloc, face_rot, face_box = [], [], [], [], []
    for i, box in enumerate(scene.boxes):
        for f, (c, fr, half) in enumerate(_face_frames(box, rots[i])):
            if not faces[i, f]:
                continue
            na = max(1, int(np.ceil(2 * half[0] / spacing[i])))
            nb = max(1, int(np.ceil(2 * half[1] / spacing[i])))
            da, db = 2 * half[0] / na, 2 * half[1] / nb
            ia, ib = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
            u = -half[0] + (ia.ravel() + rng.random(na * nb)) * da  # (K,) along t1
            v = -half[1] + (ib.ravel() + rng.random(na * nb)) * db  # (K,) along t2
            pts.append(c + u[:, None] * fr[:, 0] + v[:, None] * fr[:, 1])
            fid.append(np.full(na * nb, len(face_rot)))
            hloc.append(np.full(na * nb, np.sqrt(da * db)))
            face_rot.append(fr)
            face_box.append(i)
    p = np.concatenate(pts) if pts else np.zeros((0, 3))
    fid = np.concatenate(fid) if fid else np.zeros(0, int)
    hl = np.concatenate(hloc) if hloc else np.zeros(0)
    face_box = np.asarray(face_box, dtype=int)
    face_rot = np.asarray(face_rot).reshape(-1, 3, 3)
    # Remove samples buried inside another box (contact faces, overlaps, the ground under stones).
    owner = face_box[fid]  # (S,)
    keep = np.ones(len(p), dtype=bool)
    lo, hi = _box_aabbs(scene)
    for i in np.unique(owner):
        sel = np.flatnonzero(owner == i)
        others = np.flatnonzero(np.all(lo <= hi[i] + 1e-9, axis=1) & np.all(hi >= lo[i] - 1e-9, axis=1))
        others = others[others != i]
        if len(others):
            keep[sel] = scene.sdf(p[sel], box_ids=others) >= -1e-9
    return {"p": p[keep], "frame": fid[keep], "h": hl[keep], "face_rot": face_rot, "face_box": face_box}


def _box_aabbs(scene: AnalyticScene) -> tuple[np.ndarray, np.ndarray]:
    """Per-box world AABBs (lo, hi), each (M, 3)."""
    half = np.einsum("mij,mj->mi", np.abs(scene.rotations()), scene.boxes[:, 3:6])
    return scene.boxes[:, :3] - half, scene.boxes[:, :3] + half


def splats_from_boxes(
    scene: AnalyticScene,
    n_splats: int,
    *,
    config: SurfaceSplatConfig = SurfaceSplatConfig(),
    colors: np.ndarray | None = None,  # (M, 3) base RGB per box
    density: np.ndarray | None = None,  # (M,) relative spacing per box (2 = twice the spacing)
    faces: np.ndarray | None = None,  # (M, 6) bool, faces to sample (FACE_NAMES order)
    floater_region: tuple[np.ndarray, np.ndarray] | None = None,
    seed: int | np.random.Generator = 0,
):
    """Sample ~3DGS-like splats on the exposed box surfaces (exactly ``n_splats`` of them).

    Surfaces are sampled on a jittered grid (stratified, so the spacing is even like a trained
    3DGS), buried parts (contact faces, overlaps) are dropped, and each splat gets:

    * local frame = face frame rotated by a random angle about the normal; its **third axis is the
      face normal** (``R[:, 2]``) and carries the smallest std (flat splats);
    * tangential std ``~ tangential_factor * h`` (``h`` = local spacing) with lognormal jitter and
      in-plane anisotropy; normal std ``thickness`` times that;
    * a small position noise along the normal and in the plane;
    * opacity mostly in [0.6, 1], a fraction lower; colour = box colour plus noise.

    The last ``info["n_floaters"]`` splats are floaters: large, mostly transparent (o < 0.1)
    splats in free space, at least ``floater_clearance`` from the geometry.

    Args:
        scene: the boxes.
        n_splats: total number of splats, floaters included.
        config: the look (see :class:`SurfaceSplatConfig`).
        colors: base RGB per box in [0, 1]; default mid grey.
        density: relative spacing per box (1 = the base spacing); default all 1.
        faces: which faces of each box to sample; default all.
        floater_region: (lo, hi) world AABB for floaters; default the scene bounds.
        seed: integer seed or a numpy Generator.

    Returns:
        A :class:`~splatplan.scenes.splats.Splats` (float32, wxyz quats, linear stds).
    """
    from ..splats import Splats

    if n_splats < 1:
        raise SplatplanError(f"n_splats must be >= 1, got {n_splats}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    m = len(scene)
    colors = np.full((m, 3), 0.5) if colors is None else np.asarray(colors, np.float64).reshape(m, 3)
    density = np.ones(m) if density is None else np.asarray(density, np.float64).reshape(m)
    faces = np.ones((m, 6), bool) if faces is None else np.asarray(faces, bool).reshape(m, 6)
    cfg = config

    n_float = int(round(cfg.floater_fraction * n_splats))
    if cfg.floater_fraction > 0 and n_splats >= 1000:
        n_float = max(1, n_float)
    n_surf = n_splats - n_float

    # Pilot at a coarse spacing: the exposed area per box, in units of the base spacing.
    total = 0.0
    for i, box in enumerate(scene.boxes):
        h = box[3:6]
        areas = 4 * np.array([h[1] * h[2], h[1] * h[2], h[0] * h[2], h[0] * h[2], h[0] * h[1], h[0] * h[1]])
        total += float((areas * faces[i]).sum()) / density[i] ** 2
    h_base = np.sqrt(total / n_surf) * 3.0
    pilot = _sample_faces(scene, h_base * density, faces, rng)
    weighted = float(np.sum(pilot["h"] ** 2 / density[pilot["face_box"][pilot["frame"]]] ** 2))
    h_base = np.sqrt(weighted / n_surf) * 0.98
    for _ in range(5):
        smp = _sample_faces(scene, h_base * density, faces, rng)
        if len(smp["p"]) >= n_surf:
            break
        h_base *= 0.97 * np.sqrt(len(smp["p"]) / n_surf)
    keep = np.sort(rng.choice(len(smp["p"]), size=n_surf, replace=False))
    p, fid, hl = smp["p"][keep], smp["frame"][keep], smp["h"][keep]
    face_rot, face_box = smp["face_rot"], smp["face_box"]
    rot = face_rot[fid]  # (S, 3, 3) columns t1, t2, n
    box_id = face_box[fid]  # (S,)

    # Position noise in the face frame.
    noise = rng.standard_normal((n_surf, 3)) * np.array([cfg.tangential_noise, cfg.tangential_noise, cfg.normal_noise])
    means = p + np.einsum("sij,sj->si", rot, noise * hl[:, None])

    # Scales: (t1, t2, n) in the splat frame.
    def clipped_normal(size: int) -> np.ndarray:  # lognormal factors with the tails cut at 2.5 std
        return np.clip(rng.standard_normal(size), -2.5, 2.5)

    base = cfg.tangential_factor * hl * np.exp(cfg.size_jitter * clipped_normal(n_surf))
    a = cfg.anisotropy * np.clip(rng.standard_normal(n_surf), -2.0, 2.0)
    t_min = base * np.exp(-np.abs(a))
    thick = np.minimum(cfg.thickness * t_min * np.exp(cfg.thickness_jitter * clipped_normal(n_surf)), 0.9 * t_min)
    scales = np.stack([base * np.exp(a), base * np.exp(-a), thick], axis=1)

    # Orientation: face frame, then a random spin about the normal (local z).
    from ..splats import rotmat_to_quat

    fq = rotmat_to_quat(face_rot)  # (F, 4)
    theta = rng.uniform(0.0, np.pi, n_surf)
    spin = np.stack([np.cos(theta / 2), np.zeros(n_surf), np.zeros(n_surf), np.sin(theta / 2)], axis=1)
    quats = quat_multiply(fq[fid], spin)
    if cfg.tilt_deg > 0:  # tilt the normal about a random in-plane axis (trained splats are not exact)
        phi = np.deg2rad(cfg.tilt_deg) * np.hypot(*rng.standard_normal((2, n_surf)))  # Rayleigh angle
        psi = rng.uniform(0.0, 2 * np.pi, n_surf)
        zero = np.zeros(n_surf)
        tilt = np.stack([np.cos(phi / 2), np.sin(phi / 2) * np.cos(psi), np.sin(phi / 2) * np.sin(psi), zero], axis=1)
        quats = quat_multiply(quats, tilt)
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    quats *= np.where(quats[:, :1] < 0, -1.0, 1.0)

    low = rng.random(n_surf) < cfg.low_opacity_fraction
    opac = np.where(
        low,
        rng.uniform(*cfg.low_opacity_range, n_surf),
        1.0 - (1.0 - cfg.min_high_opacity) * rng.random(n_surf) ** 2,
    )
    cols = np.clip(colors[box_id] + cfg.color_noise * rng.standard_normal((n_surf, 3)), 0.0, 1.0)

    # Floaters.
    if n_float:
        lo, hi = floater_region if floater_region is not None else scene.bounds()
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        fm = np.zeros((0, 3))
        for _ in range(50):
            cand = rng.uniform(lo, hi, (max(64, 4 * n_float), 3))
            cand = cand[scene.sdf(cand) > cfg.floater_clearance]
            fm = np.concatenate([fm, cand])[:n_float]
            if len(fm) == n_float:
                break
        if len(fm) < n_float:
            raise SplatplanError("splats_from_boxes: no free space for floaters in floater_region")
        med = float(np.median(scales.max(axis=1)))
        big = rng.uniform(*cfg.floater_size_range, n_float) * med
        fs = big[:, None] * np.concatenate([np.ones((n_float, 1)), rng.uniform(0.3, 1.0, (n_float, 2))], axis=1)
        fq_ = rng.standard_normal((n_float, 4))
        fq_ /= np.linalg.norm(fq_, axis=1, keepdims=True)
        fq_ *= np.where(fq_[:, :1] < 0, -1.0, 1.0)
        transparent = rng.random(n_float) < cfg.floater_transparent_fraction
        fo = np.where(transparent, rng.uniform(0.01, 0.09, n_float), rng.uniform(0.1, 0.3, n_float))
        fc = np.clip(0.8 + 0.1 * rng.standard_normal((n_float, 3)), 0, 1)
        means = np.concatenate([means, fm])
        scales = np.concatenate([scales, fs])
        quats = np.concatenate([quats, fq_])
        opac = np.concatenate([opac, fo])
        cols = np.concatenate([cols, fc])

    return Splats(
        means=means,
        quats=quats,
        scales=scales,
        opacities=opac,
        colors=cols,
        source_format="analytic",
        info={
            "n_floaters": int(n_float),  # the last n_floaters splats are the floaters
            "base_spacing": float(h_base),
        },
    )
