"""Analytic scenes: unions of oriented boxes, cylinders and spheres with an exact signed distance.

A built-in scene (see :mod:`.stonehenge`) is a set of solid oriented boxes. The boxes are the
*ground truth* geometry: splats are sampled from their surfaces, and evaluation studies use
:meth:`AnalyticScene.sdf` to decide whether a query point is in collision
(``sdf(p) < r`` for a sphere robot of radius ``r``).

Units and frames
----------------
* Coordinates, and the box / cylinder / sphere rows, as in :mod:`.primitive_sdf` (scene units,
  the scene's world frame, wxyz quaternions primitive -> world).
* Primitives are indexed in one order everywhere (labels, colours, ``select``): the boxes, then
  the cylinders, then the spheres.

Exactness of the signed distance of a union
-------------------------------------------
Each primitive (box, cylinder, sphere) has an exact signed distance ``d_i`` (negative inside). For
the union we return
``min_i d_i``:

* **outside** the union (all ``d_i >= 0``) this is the exact Euclidean distance to the union,
  because the distance to a union of sets is the minimum of the distances to the sets;
* **inside** the union it is negative (the sign is right) but its magnitude may be *smaller* than
  the true depth when primitives overlap (the nearest face of the containing one may be buried
  in another): ``min_i d_i >= true_sdf``.

So ``sdf(p) < r`` (for ``r >= 0``) is the exact ground-truth collision test for a sphere of radius
``r`` centred at ``p``, which is what the studies need.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import SplatplanError
from ..splats import quat_to_rotmat
from .ellipsoid_clearance import clearance_upper_bound, ellipsoid_clearance_chunk
from .primitive_sdf import box_corners, boxes_sdf_dense, curved_sdf

__all__ = ["JSON_FORMAT", "JSON_VERSION", "AnalyticScene", "box_aabbs", "primitive_aabbs"]

#: Format tag written into JSON files produced by :meth:`AnalyticScene.to_json`.
JSON_FORMAT = "splatplan.analytic_scene"
#: Version 2 added cylinders and spheres; a box-only scene is still written as version 1 (readable by
#: older releases), and version 1 files load unchanged.
JSON_VERSION = 2


def _rows(x, width: int, what: str, size_cols: slice, quat_cols: slice | None) -> np.ndarray:
    """Validated float64 (N, width) primitive rows (sizes > 0, finite, quaternions normalised)."""
    b = np.array(x, dtype=np.float64)
    if b.ndim == 1 and b.size == 0:
        b = b.reshape(0, width)
    if b.ndim != 2 or b.shape[1] != width:
        raise SplatplanError(f"AnalyticScene.{what} has shape {b.shape}, expected (N, {width})")
    if not np.all(np.isfinite(b)):
        raise SplatplanError(f"AnalyticScene.{what} contains NaN/Inf")
    if np.any(b[:, size_cols] <= 0):
        raise SplatplanError(f"AnalyticScene.{what}: sizes (half-extents, radii, half-heights) must be > 0")
    if quat_cols is not None:
        qn = np.linalg.norm(b[:, quat_cols], axis=1)
        if np.any(qn < 1e-12):
            raise SplatplanError(f"AnalyticScene.{what}: zero quaternion")
        b[:, quat_cols] /= qn[:, None]
    return np.ascontiguousarray(b)


@dataclass
class AnalyticScene:
    """A union of solid oriented boxes, cylinders and spheres with an exact signed distance (see
    the module docstring).

    Attributes:
        boxes: float64 (M, 10) rows ``(cx, cy, cz, hx, hy, hz, qw, qx, qy, qz)``; centre in the
            world frame (scene units), half-extents in the box frame, wxyz unit quaternion
            rotating the box frame into the world frame.
        labels: one short name per primitive, boxes first, then cylinders, then spheres (e.g.
            "ground", "sarsen", "Can1"); free-form.
        meta: free-form JSON-serialisable metadata (units, robot radius, generator, ...).
        cylinders: float64 (C, 9) rows ``(cx, cy, cz, radius, half_height, qw, qx, qy, qz)``; the
            axis is the cylinder's own z; wxyz cylinder -> world.
        spheres: float64 (S, 4) rows ``(cx, cy, cz, radius)``.
    """

    boxes: np.ndarray
    labels: list[str] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    cylinders: np.ndarray = field(default_factory=lambda: np.zeros((0, 9)))
    spheres: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))

    def __post_init__(self) -> None:
        self.boxes = _rows(self.boxes, 10, "boxes", size_cols=slice(3, 6), quat_cols=slice(6, 10))
        self.cylinders = _rows(self.cylinders, 9, "cylinders", size_cols=slice(3, 5), quat_cols=slice(5, 9))
        self.spheres = _rows(self.spheres, 4, "spheres", size_cols=slice(3, 4), quat_cols=None)
        n_b, n_c, n_s = len(self.boxes), len(self.cylinders), len(self.spheres)
        if not self.labels:
            self.labels = ["box"] * n_b + ["cylinder"] * n_c + ["sphere"] * n_s
        self.labels = [str(s) for s in self.labels]
        if len(self.labels) != n_b + n_c + n_s:
            raise SplatplanError(f"AnalyticScene: {len(self.labels)} labels for {n_b} boxes + {n_c} cylinders + {n_s} spheres")

    def __len__(self) -> int:
        """Number of primitives (boxes + cylinders + spheres)."""
        return int(len(self.boxes) + len(self.cylinders) + len(self.spheres))

    @property
    def kinds(self) -> list[str]:
        """Primitive kind per index ("box", "cylinder", "sphere"), in the labels' order."""
        return ["box"] * len(self.boxes) + ["cylinder"] * len(self.cylinders) + ["sphere"] * len(self.spheres)

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
        """Signed distance (P,) float64 from points to the union of the primitives (negative inside).

        Exact outside the union; inside, ``min`` of the box distances (right sign, magnitude may be
        too small where boxes overlap; see the module docstring). Memory is bounded: points are
        processed in chunks so that temporaries stay around ``chunk * M * 3`` float64 values.

        The broad phase bins the points into cells and evaluates, per cell, only the boxes that can
        hold the minimum (AABB lower bound <= the cell's best upper bound ``max |corner - c_m|``);
        it changes nothing in the result, only the speed.

        Args:
            points: (P, 3) or (3,) world coordinates, scene units.
            chunk: points per chunk; default keeps each temporary below ~8 MB.
            box_ids: optional subset of box indices to take the union over (then only those boxes,
                no cylinders or spheres; default: every primitive).
            broad_phase: cull boxes per cell of points (exact; off = brute force over all boxes).

        Returns:
            float64 (P,) signed distances (scene units); a (3,) input gives a (1,) result.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = self._box_sdf(p, self.boxes if box_ids is None else self.boxes[box_ids], chunk, broad_phase)
        if box_ids is None and (len(self.cylinders) or len(self.spheres)):
            out = np.minimum(out, curved_sdf(p, self.cylinders, self.spheres, chunk))
        return out

    @staticmethod
    def _box_sdf(p: np.ndarray, boxes: np.ndarray, chunk: int | None, broad_phase: bool) -> np.ndarray:
        """min over ``boxes`` (M, 10) of the exact box SDFs at p (P, 3), (P,) float64 (inf when M = 0)."""
        rot = quat_to_rotmat(boxes[:, 6:10]).reshape(-1, 3, 3)
        m = boxes.shape[0]
        if m == 0 or p.shape[0] == 0:
            return np.full(p.shape[0], np.inf)
        if not broad_phase or p.shape[0] < 4096 or m < 8:
            return boxes_sdf_dense(p, boxes, rot, chunk)
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
            out[idx] = boxes_sdf_dense(p[idx], boxes[cand], rot[cand], chunk)
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
        """Smallest signed distance from each solid ellipsoid to the union of primitives, (...,) float64.

        ``clearance(E) = min over points p of E of sdf(p) = min_i min_{p in E} d_i(p)``:

        * positive: the Euclidean distance between the ellipsoid and the nearest primitive, as its
          certified lower bound (never above the true distance; within 1e-7 m of the closest pair
          found in typical cases, up to ~20 um short when the sets nearly touch at a grazing angle);
        * negative: minus the depth of the ellipsoid's deepest point inside a primitive (the right
          sign; for overlapping primitives the depth inside one of them, see the module docstring).

        Spheres are solved in closed form: ``dist(sphere centre, E) - radius`` (Newton projection
        onto the ellipsoid; exact in both signs). Boxes and cylinders are solved as below (the
        cylinder's projection clips the radius and the height, its support along n is
        ``r |n_xy| + h |n_z|``, its depth ``min(r - |p_xy|, h - |p_z|)``).

        Each ellipsoid-box problem is convex (the box SDF is convex, the ellipsoid is convex). The
        positive case is solved by alternating projections between the ellipsoid and the box from
        the best of 145 surface/interior samples; the length of the final closest-pair candidate is
        an upper bound, and the returned value is the separating-plane lower bound
        ``n.c - |M^T n| - sum_k h_k |n_k|`` (``return_bounds`` gives both). Where no plane certifies
        a positive gap (the sets touch or intersect without any sample inside), and in the negative
        case, ``min_k (h_k - |p_k|)`` is maximised over the ellipsoid by projected subgradient
        ascent (400 steps) from the best sample; the depth it finds is a feasible point's depth, so
        the sign is certain and the magnitude at most the true depth (tests: within 0.2 mm); an
        uncertified pair where no point inside is found gets 0.
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
        c, rot_e, a, shape = self._ellipsoids(centers, quats, semi_axes)
        out = np.full(len(c), np.inf)
        lo_b, hi_b = np.full(len(c), np.inf), np.full(len(c), np.inf)
        if len(self) and len(c):
            for s in range(0, len(c), chunk):
                sl = slice(s, s + chunk)
                out[sl], lo_b[sl], hi_b[sl] = ellipsoid_clearance_chunk(self, c[sl], rot_e[sl], a[sl])
        if return_bounds:
            return out.reshape(shape), lo_b.reshape(shape), hi_b.reshape(shape)
        return out.reshape(shape)

    #: (m) a pair whose centre bound is this far above the smallest upper bound is not solved by
    #: :meth:`min_ellipsoid_clearance`: far above the solver's error (its value is at most ~20 um
    #: below the true clearance), so the skipped pairs cannot hold the minimum
    MIN_CLEARANCE_PAD = 1e-4

    def min_ellipsoid_clearance(self, centers: np.ndarray, quats: np.ndarray | None, semi_axes: np.ndarray, *, chunk: int = 4096) -> float:
        """``ellipsoid_clearance(centers, quats, semi_axes).min()`` (+inf for no ellipsoid), solving
        only the ellipsoid-primitive pairs that can hold the minimum.

        Every ellipsoid's centre gives an upper bound on its clearance (:meth:`ellipsoid_clearance`'s
        broad phase); the smallest, U, bounds the minimum. A pair whose lower bound ``d(c) - a_max``
        exceeds ``U + MIN_CLEARANCE_PAD`` has a clearance (and a computed value) above the minimum,
        so it is skipped; the others are solved exactly as :meth:`ellipsoid_clearance` solves them.
        The value is the same; a trajectory's minimum over thousands of ellipsoids, most of them
        far from the geometry, costs a fraction of the full evaluation.
        """
        c, rot_e, a, _ = self._ellipsoids(centers, quats, semi_axes)
        if not (len(self) and len(c)):
            return float("inf")
        u = min(clearance_upper_bound(self, c[s : s + chunk], a[s : s + chunk]) for s in range(0, len(c), chunk))
        best = float("inf")
        for s in range(0, len(c), chunk):
            sl = slice(s, s + chunk)
            best = min(best, float(ellipsoid_clearance_chunk(self, c[sl], rot_e[sl], a[sl], cutoff=u + self.MIN_CLEARANCE_PAD)[0].min()))
        return best

    def _ellipsoids(self, centers, quats, semi_axes) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple]:
        """Validated ellipsoids, flat: centres (N, 3), rotations ellipsoid -> world (N, 3, 3),
        semi-axes (N, 3), and the batch shape."""
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
        rot_e = quat_to_rotmat(q / np.linalg.norm(q, axis=1, keepdims=True)).reshape(-1, 3, 3) if len(c) else np.zeros((0, 3, 3))
        return c, rot_e, a, shape

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
        """World-frame axis-aligned bounds (min, max) of all primitives, each float64 (3,)."""
        if len(self) == 0:
            raise SplatplanError("the analytic scene has no primitives")
        lo, hi = primitive_aabbs(self)
        return lo.min(0), hi.max(0)

    def corners(self) -> np.ndarray:
        """float64 (M, 8, 3) world corners of every box."""
        return np.stack([box_corners(b) for b in self.boxes]) if len(self) else np.zeros((0, 8, 3))

    def copy(self) -> "AnalyticScene":
        """A deep copy (arrays, labels and meta)."""
        return AnalyticScene(self.boxes.copy(), list(self.labels), json.loads(json.dumps(self.meta)), self.cylinders.copy(), self.spheres.copy())

    def select(self, mask_or_idx) -> "AnalyticScene":
        """A new scene with the chosen primitives (boolean mask or index array over all primitives,
        boxes first, then cylinders, then spheres)."""
        idx = np.arange(len(self))[mask_or_idx]
        nb, nc = len(self.boxes), len(self.cylinders)
        b, cy, sp = idx[idx < nb], idx[(idx >= nb) & (idx < nb + nc)] - nb, idx[idx >= nb + nc] - nb - nc
        labels = [self.labels[i] for i in np.concatenate([b, cy + nb, sp + nb + nc])]
        return AnalyticScene(self.boxes[b].copy(), labels, dict(self.meta), self.cylinders[cy].copy(), self.spheres[sp].copy())

    # ------------------------------------------------------------------ serialisation
    def to_json(self) -> dict:
        """A JSON-serialisable dict (float64 values kept with full precision)."""
        d = {
            "format": JSON_FORMAT,
            "version": JSON_VERSION if len(self.cylinders) or len(self.spheres) else 1,
            "box_layout": "cx cy cz hx hy hz qw qx qy qz (half-extents in the box frame; wxyz box->world)",
            "boxes": self.boxes.tolist(),
            "labels": list(self.labels),
            "meta": self.meta,
        }
        if len(self.cylinders) or len(self.spheres):  # version 2 (a box-only scene stays readable by version-1 readers)
            d["cylinder_layout"] = "cx cy cz radius half_height qw qx qy qz (axis = the cylinder's z; wxyz cylinder->world)"
            d["cylinders"] = self.cylinders.tolist()
            d["sphere_layout"] = "cx cy cz radius"
            d["spheres"] = self.spheres.tolist()
        return d

    @classmethod
    def from_json(cls, d: dict) -> "AnalyticScene":
        """Inverse of :meth:`to_json`; raises :class:`SplatplanError` on a malformed dict."""
        if not isinstance(d, dict) or d.get("format") != JSON_FORMAT:
            raise SplatplanError(f"not an analytic scene JSON (expected 'format': '{JSON_FORMAT}')")
        if int(d.get("version", -1)) > JSON_VERSION:
            raise SplatplanError(f"analytic scene JSON version {d.get('version')} is newer than supported ({JSON_VERSION})")
        rows = {}
        for key, width in (("boxes", 10), ("cylinders", 9), ("spheres", 4)):
            try:
                rows[key] = np.asarray(d[key] if key == "boxes" else d.get(key, []), dtype=np.float64).reshape(-1, width)
            except (KeyError, ValueError, TypeError) as e:
                raise SplatplanError(f"analytic scene JSON: bad {key!r} field ({e})") from e
        return cls(rows["boxes"], list(d.get("labels", [])), dict(d.get("meta", {})), rows["cylinders"], rows["spheres"])

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


def primitive_aabbs(scene: AnalyticScene) -> tuple[np.ndarray, np.ndarray]:
    """Per-primitive world AABBs (lo, hi), each (len(scene), 3), boxes, cylinders, spheres."""
    lo, hi = box_aabbs(scene)
    cyl, sph = scene.cylinders, scene.spheres
    if len(cyl):
        axis = quat_to_rotmat(cyl[:, 5:9]).reshape(-1, 3, 3)[:, :, 2]  # (C, 3) world axis
        # a disk of radius r with normal k extends r sqrt(1 - k_i^2) along world axis i
        half = np.abs(axis) * cyl[:, 4:5] + cyl[:, 3:4] * np.sqrt(np.maximum(1.0 - axis**2, 0.0))
        lo, hi = np.concatenate([lo, cyl[:, :3] - half]), np.concatenate([hi, cyl[:, :3] + half])
    if len(sph):
        lo, hi = np.concatenate([lo, sph[:, :3] - sph[:, 3:4]]), np.concatenate([hi, sph[:, :3] + sph[:, 3:4]])
    return lo, hi


def box_aabbs(scene: AnalyticScene) -> tuple[np.ndarray, np.ndarray]:
    """Per-box world AABBs (lo, hi), each (M, 3)."""
    half = np.einsum("mij,mj->mi", np.abs(scene.rotations()), scene.boxes[:, 3:6])
    return scene.boxes[:, :3] - half, scene.boxes[:, :3] + half
