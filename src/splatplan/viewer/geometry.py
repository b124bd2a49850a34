"""Geometry the viewer draws: ellipsoid meshes, per-splat conservative distances, trees, field slices.

Pure numpy (no viser import), so it is testable without a browser. Frames: everything is in the
scene's world frame and units; quaternions are wxyz.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..scenes.splats import quat_to_rotmat


@lru_cache(maxsize=4)
def unit_sphere_mesh(subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """An icosphere of radius 1: vertices (V, 3) float32, faces (F, 3) int32."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]  # fmt: skip
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]  # fmt: skip
    verts = [np.asarray(p, dtype=np.float64) / np.linalg.norm(p) for p in v]
    faces = list(f)
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.asarray(verts, dtype=np.float32), np.asarray(faces, dtype=np.int32)


def ellipsoid_mesh(center, quat, semi_axes, subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Mesh of one ellipsoid (world frame): vertices (V, 3) float32, faces (F, 3) int32."""
    v, f = unit_sphere_mesh(subdivisions)
    r = quat_to_rotmat(np.asarray(quat, dtype=np.float64))
    verts = (v * np.asarray(semi_axes, dtype=np.float64)) @ r.T + np.asarray(center, dtype=np.float64)
    return verts.astype(np.float32), f


def splat_s2_tilde(
    means: np.ndarray,  # (N, 3) splat means
    splat_quats: np.ndarray,  # (N, 4) wxyz
    scales: np.ndarray,  # (N, 3) linear stds
    centers: np.ndarray,  # (E, 3) ellipsoid centres
    quats: np.ndarray,  # (E, 4) wxyz
    semi_axes: np.ndarray,  # (E, 3)
    n_sigma: float,
    candidates: list[np.ndarray] | None = None,  # per ellipsoid: indices of splats to evaluate (None = all)
    linearize: str = "distance",  # MetricConfig.linearize
) -> np.ndarray:
    """Per splat: min over the ellipsoids of the metric's s2~ (N,), for colouring.

    Splats not among any ellipsoid's candidates get +inf. Evaluates the metric's own reference
    (``splatplan.metric.reference.conservative_s2_ref``) on each ellipsoid's candidates.
    """
    from ..metric.reference import conservative_s2_ref, link_matrices

    n = means.shape[0]
    out = np.full(n, np.inf)
    a = link_matrices(np.asarray(quats, dtype=np.float64).reshape(-1, 4), semi_axes, len(centers))  # (E, 3, 3)
    for e in range(len(centers)):
        idx = np.arange(n) if candidates is None else candidates[e]
        if len(idx) == 0:
            continue
        _, s2t = conservative_s2_ref(means[idx], splat_quats[idx], scales[idx], centers[e : e + 1], a[e : e + 1], n_sigma, linearize)
        np.minimum.at(out, idx, s2t[0])
    return out


def tree_segments(nodes: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """RRT tree as line segments (M, 2, 3): one segment from each non-root node to its parent.

    ``nodes`` (N, D) with D >= 2 (planar trees get z = 0; only the first three coordinates are
    drawn), ``parents`` (N,) int with -1 at roots.
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    parents = np.asarray(parents).astype(np.int64).reshape(-1)
    xyz = np.zeros((len(nodes), 3))
    xyz[:, : min(3, nodes.shape[1])] = nodes[:, :3]
    child = np.flatnonzero(parents >= 0)
    return np.stack([xyz[child], xyz[parents[child]]], axis=1).astype(np.float32)


def polyline_segments(points: np.ndarray) -> np.ndarray:
    """A polyline (P, 3) as segments (P-1, 2, 3)."""
    p = np.asarray(points, dtype=np.float32)
    return np.stack([p[:-1], p[1:]], axis=1)


def colormap(values: np.ndarray, vmin: float, vmax: float) -> np.ndarray:
    """Values -> uint8 RGB (..., 3) with matplotlib's viridis (low = dark purple: close to a splat)."""
    from matplotlib import colormaps

    t = np.clip((np.nan_to_num(values, posinf=vmax) - vmin) / max(vmax - vmin, 1e-12), 0.0, 1.0)
    return (colormaps["viridis"](t)[..., :3] * 255).astype(np.uint8)
