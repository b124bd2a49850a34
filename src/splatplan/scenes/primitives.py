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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from .splats import quat_to_rotmat

__all__ = ["AnalyticScene", "box_sdf", "box_corners", "make_box"]

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
        # Cached (M, 3, 3) box -> world rotations.
        self._rot = quat_to_rotmat(self.boxes[:, 6:10]).reshape(-1, 3, 3)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    # ------------------------------------------------------------------ geometry
    def rotations(self) -> np.ndarray:
        """float64 (M, 3, 3) box-to-world rotation matrices."""
        return self._rot.copy()

    def sdf(self, points: np.ndarray, *, chunk: int | None = None, box_ids: np.ndarray | None = None) -> np.ndarray:
        """Signed distance (P,) float64 from points to the union of boxes (negative inside).

        Exact outside the union; inside, ``min`` of the box distances (right sign, magnitude may be
        too small where boxes overlap; see the module docstring). Memory is bounded: points are
        processed in chunks so that temporaries stay around ``chunk * M * 3`` float64 values.

        Args:
            points: (P, 3) or (3,) world coordinates, scene units.
            chunk: points per chunk; default keeps each temporary below ~8 MB.
            box_ids: optional subset of box indices to take the union over (default: all).

        Returns:
            float64 (P,) signed distances (scene units); a (3,) input gives a (1,) result.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        boxes, rot = self.boxes, self._rot
        if box_ids is not None:
            boxes, rot = boxes[box_ids], rot[box_ids]
        m = boxes.shape[0]
        out = np.full(p.shape[0], np.inf)
        if m == 0 or p.shape[0] == 0:
            return out
        if chunk is None:
            chunk = max(256, int(1_000_000 // (3 * m)))
        c = boxes[:, :3]  # (M, 3)
        h = boxes[:, 3:6]  # (M, 3)
        for s in range(0, p.shape[0], chunk):
            pc = p[s : s + chunk]  # (C, 3)
            d = pc[:, None, :] - c[None, :, :]  # (C, M, 3) world offsets
            local = np.einsum("cmi,mij->cmj", d, rot)  # R^T d, (C, M, 3)
            np.abs(local, out=local)
            local -= h[None]
            inside = np.minimum(local.max(axis=2), 0.0)  # (C, M)
            np.maximum(local, 0.0, out=local)
            outside = np.sqrt(np.einsum("cmi,cmi->cm", local, local))
            out[s : s + chunk] = (outside + inside).min(axis=1)
        return out

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
