"""Small synthetic splat scenes for the planner tests (scene units, z-up world, wxyz quats)."""

from __future__ import annotations

import numpy as np

from splatplan.scenes.splats import Splats, rotmat_to_quat


def box_surface_splats(lo, hi, spacing: float, rng: np.random.Generator, sigma_t: float = 0.003, sigma_n: float = 0.0005):
    """Splats on the 6 faces of an axis-aligned box: flat along the face normal.

    Returns means (M, 3), quats (M, 4) wxyz, scales (M, 3).
    """
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    means, quats, scales = [], [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        nu = max(2, int(np.ceil((hi[u] - lo[u]) / spacing)) + 1)
        nv = max(2, int(np.ceil((hi[v] - lo[v]) / spacing)) + 1)
        gu, gv = np.meshgrid(np.linspace(lo[u], hi[u], nu), np.linspace(lo[v], hi[v], nv), indexing="ij")
        for side in (lo[axis], hi[axis]):
            m = np.zeros((gu.size, 3))
            m[:, u], m[:, v], m[:, axis] = gu.ravel(), gv.ravel(), side
            r = np.zeros((3, 3))
            r[:, 0], r[:, 1], r[:, 2] = np.eye(3)[u], np.eye(3)[v], np.eye(3)[axis]
            if np.linalg.det(r) < 0:
                r[:, 1] *= -1
            means.append(m + rng.normal(0, 0.0005, m.shape))
            quats.append(np.repeat(rotmat_to_quat(r)[None], len(m), axis=0))
            scales.append(np.tile([sigma_t, sigma_t, sigma_n], (len(m), 1)))
    return np.concatenate(means), np.concatenate(quats), np.concatenate(scales)


def make_scene(boxes, spacing: float = 0.012, seed: int = 0, **kw) -> Splats:
    """A Splats scene made of box surfaces; boxes = [(lo (3,), hi (3,)), ...]."""
    rng = np.random.default_rng(seed)
    parts = [box_surface_splats(lo, hi, spacing, rng, **kw) for lo, hi in boxes]
    means = np.concatenate([p[0] for p in parts])
    quats = np.concatenate([p[1] for p in parts])
    scales = np.concatenate([p[2] for p in parts])
    n = len(means)
    return Splats(means, quats, scales, np.full(n, 0.9), np.full((n, 3), 0.5))


#: one wall across the plane z = 0.06 between start (-0.15, 0, 0.06) and goal (0.15, 0, 0.06);
#: the way around is through y > 0.12
WALL = [((-0.01, -0.25, 0.0), (0.01, 0.12, 0.12))]


def wall_scene(seed: int = 0) -> Splats:
    return make_scene(WALL, seed=seed)


def make_checker(splats: Splats, n_sigma: float = 1.0):
    """The Warp-backed checker the planners use in production."""
    from splatplan.metric import CollisionChecker

    return CollisionChecker(splats, n_sigma=n_sigma, backend="warp")
