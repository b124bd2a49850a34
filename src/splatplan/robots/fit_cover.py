"""Tight and safe link models: a union of ellipsoids that contains the link's solid and stays close to it.

One enclosing ellipsoid per link is safe but loose (a cylinder's is already sqrt(3) = 1.73x its
volume). Here the union does the work:

1. **Targets.** Every collision element of a link (mesh or box) becomes a watertight solid in the
   link frame (a mesh that is not watertight is replaced by its convex hull, which contains it).
   Target points: surface samples, interior samples and the vertices.
2. **Outside distance.** An occupancy grid (pitch ``FitConfig.pitch``) and its Euclidean distance
   transform give, for any point, its distance to the solid (0 inside), to about one pitch.
3. **Candidates.** Minimum-volume enclosing ellipsoids (:func:`~splatplan.robots.ellipsoid.mvee`) of
   local clusters of target points (k-nearest neighbours of farthest-point seeds at four scales,
   and slabs between pairs of cuts along each principal axis), plus variants stretched along one
   axis or flattened across two (the other axes shrink to the cluster). Each is then shrunk, axis
   by axis in proportion to its overshoot, until its surface stays within ``FitConfig.reach``
   minus a two-pitch safety band of the solid; the 3 variants per cluster covering the most
   target points are kept.
4. **Greedy cover.** Candidates are chosen by (target points newly covered) / (volume newly added
   outside the solid + a fixed cost per ellipsoid) until every target point is covered or
   ``FitConfig.max_per_link`` is reached; up to three times, small candidates seeded at the target
   points still uncovered join the pool and the cover is chosen again.
5. **Certificate and repair.** Each solid is split into simplices: tetrahedra from a centre point
   to every face when the solid is star-shaped about that point (checked exactly: every face's
   plane has the centre strictly on its inner side), otherwise its surface triangles. A simplex
   whose vertices all lie in ONE ellipsoid lies in it (ellipsoids are convex); other simplices are
   bisected along their longest edge, down to ``FitConfig.max_depth`` levels; a simplex still not
   inside one ellipsoid makes the ellipsoid that needs the smallest uniform scale-up grow (about
   its centre, so everything it contained stays contained) until it holds the simplex.

**Guarantee.** When the certificate ends, every simplex lies inside one ellipsoid, so the union
contains the whole solid (star-shaped case: the tetrahedra partition it; the Panda's links are all
star-shaped) or its whole surface (otherwise; the interior is then checked on samples only). This
is exact up to float rounding, covered by a relative margin ``CONTAIN_EPS`` on the scale-ups and a
final 1e-9 relative growth. The reach and the volume are not guaranteed: they are measured
(:mod:`splatplan.robots.fit_measure`) and reported per link.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from .ellipsoid import CONTAIN_EPS, mahalanobis, mvee, sphere_points, surface_of  # noqa: F401 (re-exported)
from .solids import inside_any, occupancy_grid, sample_solids, simplices_of, solids_of  # noqa: F401 (re-exported)

#: Version of the cover fitter: part of the fit cache key (bump when results change).
COVER_VERSION = 1


@dataclass(frozen=True)
class FitConfig:
    """Knobs of the tight cover fitter (all lengths in metres)."""

    #: Largest distance the model may reach beyond the link's solid (the candidates' limit).
    reach: float = bounded(0.015, gt=0, le=1.0)
    #: Most ellipsoids per link (the greedy cover stops there; the repair then grows them).
    max_per_link: int = bounded(14, ge=1, le=256)
    #: Cost of one more ellipsoid, as a fraction of the link's volume (trades count for tightness).
    ellipsoid_cost: float = bounded(0.1, ge=0)
    #: Occupancy-grid pitch for the outside distance (0: extent / 80, clipped to [0.5, 3] mm).
    pitch: float = bounded(0.0, ge=0, le=0.1)
    #: Target points per link (surface + interior samples).
    n_points: int = bounded(3000, ge=100, le=100_000)
    #: Longest-edge bisections per simplex before the repair grows an ellipsoid.
    max_depth: int = bounded(14, ge=0, le=30)
    #: Farthest-point seeds of the nearest-neighbour clusters (4 scales each).
    n_seeds: int = bounded(16, ge=1, le=1024)
    #: Cuts along each principal axis for the slab clusters (every pair of cuts is a slab).
    n_cuts: int = bounded(7, ge=2, le=64)
    #: Certificate repairs: a gap needing a larger uniform scale-up of every ellipsoid than this gets
    #: a new small ellipsoid instead (the MVEE of the gap and its nearest target points; inf: never,
    #: which measured tighter on the Panda).
    max_grow: float = bounded(math.inf, gt=1.0, allow_inf=True)
    #: Seed of every random choice (the fit is deterministic).
    seed: int = bounded(0, ge=0, le=2**32 - 1)

    def validate(self) -> "FitConfig":
        check_config(self)  # declared ranges and finiteness
        if not (math.isfinite(self.reach) and self.reach > 0):
            raise SplatplanError(f"fit reach must be > 0 m, got {self.reach}")
        if self.max_per_link < 1:
            raise SplatplanError(f"fit max_per_link must be >= 1, got {self.max_per_link}")
        if not (self.ellipsoid_cost >= 0):
            raise SplatplanError(f"fit ellipsoid_cost must be >= 0, got {self.ellipsoid_cost}")
        if not self.max_grow > 1.0:
            raise SplatplanError(f"fit max_grow must be > 1, got {self.max_grow}")
        if self.pitch < 0 or self.n_points < 100 or self.max_depth < 0 or self.n_seeds < 1 or self.n_cuts < 2:
            raise SplatplanError("fit pitch must be >= 0, n_points >= 100, max_depth >= 0, n_seeds >= 1, n_cuts >= 2")
        return self


# --------------------------------------------------------------------------- solids


class OutsideDistance:
    """Distance to the union of solids (0 inside) from an occupancy grid and its distance transform.

    Query error: at most about one pitch (grid centres, nearest-voxel lookup). Points off the grid
    get +inf (the grid spans the solids' bounds plus ``margin``).
    """

    def __init__(self, solids: list, pitch: float, margin: float):
        from scipy.ndimage import distance_transform_edt

        self.lo, self.pitch, self.shape, self.centres, occ = occupancy_grid(solids, pitch, margin, min_cells=1)
        self.dist = distance_transform_edt(~occ, sampling=pitch)  # (X, Y, Z) metres
        self.occ = occ.reshape(-1)

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        idx = np.floor((pts - self.lo) / self.pitch).astype(np.int64)  # (N, 3)
        ok = np.all((idx >= 0) & (idx < self.shape), axis=1)
        out = np.full(len(pts), np.inf)
        i = idx[ok]
        out[ok] = self.dist[i[:, 0], i[:, 1], i[:, 2]]
        return out


# --------------------------------------------------------------------------- candidates


def _fps(pts: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of k farthest-point samples."""
    idx = [int(rng.integers(len(pts)))]
    d = np.linalg.norm(pts - pts[idx[0]], axis=1)
    for _ in range(min(k, len(pts)) - 1):
        j = int(np.argmax(d))
        idx.append(j)
        d = np.minimum(d, np.linalg.norm(pts - pts[j], axis=1))
    return np.array(idx)


def _refit_axes(e: tuple, pts: np.ndarray, stretch: np.ndarray) -> tuple | None:
    """Stretch some semi-axes of e by ``stretch`` (3,) (>= 1: those axes are kept fixed at s * stretch)
    and shrink the others by one common factor, the least that still contains pts (None if impossible)."""
    c, r, s = e
    s2 = s * stretch
    fixed = stretch > 1.0
    local = (pts - c) @ r / s2  # (N, 3)
    free2 = (local[:, ~fixed] ** 2).sum(axis=1)
    room = 1.0 - (local[:, fixed] ** 2).sum(axis=1)
    if np.any(room <= 1e-9):
        return None
    f = math.sqrt(float(np.max(free2 / room)))
    out = s2.copy()
    out[~fixed] *= f
    return (c, r, out * (1.0 + CONTAIN_EPS))


#: Stretches tried on each cluster's MVEE: one axis longer (elongated ellipsoids along a link) or two
#: (flattened ones across it); the remaining axes shrink to the cluster.
STRETCHES = [np.ones(3)] + [np.where(np.arange(3) == j, k, 1.0) for j in range(3) for k in (1.25, 1.6, 2.0, 2.6, 3.4)] + [
    np.where(np.arange(3) != j, k, 1.0) for j in range(3) for k in (1.15, 1.35, 1.7)
]


def _variants(cluster: np.ndarray, dist: OutsideDistance, limit: float, dirs: np.ndarray, targets: np.ndarray, keep: int = 3) -> list:
    """Ellipsoids that contain the cluster and stay within ``limit`` of the solid: its MVEE and
    stretched / flattened variants of it."""
    if len(cluster) < 4:
        return []
    base = mvee(cluster, tol=3e-2, max_iter=3000)
    out = []
    for st in STRETCHES:
        e = base if st is STRETCHES[0] else _refit_axes(base, cluster, st)
        if e is not None:
            e = _shrink_inside(e, dist, limit, dirs)
        if e is not None:
            out.append(e)
    if len(out) > keep:  # the variants that cover the most target points
        hits = np.array([(mahalanobis(targets, *e) <= 1.0).sum() for e in out])
        out = [out[i] for i in np.argsort(-hits, kind="stable")[:keep]]
    return out


def _shrink_inside(e: tuple, dist: OutsideDistance, limit: float, dirs: np.ndarray, steps: int = 40) -> tuple | None:
    """Shrink the semi-axes of e (each by its share of the overshoot) until its surface stays
    within ``limit`` of the solid; None when it would vanish."""
    c, r, s = e
    s = s.copy()
    s0 = s.max()
    for _ in range(steps):
        d = dist(surface_of((c, r, s), dirs))
        bad = d > limit
        if not bad.any():
            return (c, r, s)
        over = np.minimum(d[bad] - limit, 10.0 * limit)  # +inf (off the grid) counts as far
        w = (over[:, None] * np.abs(dirs[bad]) * s).sum(axis=0)  # (3,) overshoot per axis
        s = s * (1.0 - 0.12 * w / w.max())
        if s.min() < 1e-3 * s0:
            return None
    return None


def candidates(targets: np.ndarray, dist: OutsideDistance, limit: float, rng: np.random.Generator, n_seeds: int = 16, n_cuts: int = 7) -> list:
    from scipy.spatial import cKDTree

    dirs = sphere_points(400)
    out = []
    n = len(targets)
    tree = cKDTree(targets)
    for seed in _fps(targets, n_seeds, rng):
        for frac in (0.05, 0.12, 0.25, 0.45):
            k = max(8, int(frac * n))
            _, nb = tree.query(targets[seed], k=k)
            out += _variants(targets[nb], dist, limit, dirs, targets)
    ctr = targets.mean(axis=0)
    axes = np.linalg.svd(targets - ctr, full_matrices=False)[2]
    for ax in axes:
        t = (targets - ctr) @ ax
        cuts = np.quantile(t, np.linspace(0.0, 1.0, n_cuts))
        for i in range(len(cuts)):
            for j in range(i + 1, len(cuts)):
                sel = (t >= cuts[i]) & (t <= cuts[j])
                if sel.sum() >= 8:
                    out += _variants(targets[sel], dist, limit, dirs, targets)
    return out


# --------------------------------------------------------------------------- greedy cover


def greedy_cover(cands: list, targets: np.ndarray, waste_pts: np.ndarray, cell_volume: float, volume: float, cfg: FitConfig) -> list:
    """Chosen ellipsoids [(c, R, s), ...] covering the target points (see the module docstring)."""
    if not cands:
        return []
    in_t = np.array([mahalanobis(targets, *e) <= 1.0 for e in cands])  # (C, N)
    in_w = np.array([mahalanobis(waste_pts, *e) <= 1.0 for e in cands])  # (C, W)
    covered = np.zeros(len(targets), dtype=bool)
    wasted = np.zeros(len(waste_pts), dtype=bool)
    per_point = volume / len(targets)
    chosen: list = []  # of the candidates (centre, rotation, semi-axes)
    while not covered.all() and len(chosen) < cfg.max_per_link:
        gain = (in_t & ~covered).sum(axis=1) * per_point
        cost = (in_w & ~wasted).sum(axis=1) * cell_volume + cfg.ellipsoid_cost * volume
        score = gain / cost
        j = int(np.argmax(score))
        if gain[j] <= 0:
            break
        chosen.append(cands[j])
        covered |= in_t[j]
        wasted |= in_w[j]
    return chosen


# --------------------------------------------------------------------------- certificate


def _bisect(simp: np.ndarray) -> np.ndarray:
    """Split simplices (K, m, 3) along their longest edge -> (2K, m, 3)."""
    m = simp.shape[1]
    pairs = [(i, j) for i in range(m) for j in range(i + 1, m)]
    lens = np.stack([np.linalg.norm(simp[:, i] - simp[:, j], axis=1) for i, j in pairs], axis=1)
    best = np.argmax(lens, axis=1)
    a = np.array([p[0] for p in pairs])[best]
    b = np.array([p[1] for p in pairs])[best]
    k = np.arange(len(simp))
    mid = 0.5 * (simp[k, a] + simp[k, b])
    s1, s2 = simp.copy(), simp.copy()
    s1[k, a] = mid
    s2[k, b] = mid
    return np.concatenate([s1, s2])


def _grow_to(ells: list, pts: np.ndarray, stats: dict, patch=None, max_grow: float = np.inf) -> None:
    """Scale up (about its centre) the ellipsoid needing the least growth to hold all of pts (m, 3);
    when that growth exceeds ``max_grow``, add ``patch(pts)`` (a new ellipsoid holding pts) instead."""
    worst = np.array([mahalanobis(pts, *e).max() for e in ells])
    e = int(np.argmin(worst))
    if worst[e] <= 1.0:
        return
    if patch is not None and worst[e] > max_grow:
        new = patch(pts)
        if mahalanobis(pts, *new).max() <= 1.0:
            ells.append(new)
            stats["patches"] = stats.get("patches", 0) + 1
            return
    f = float(worst[e]) * (1.0 + CONTAIN_EPS)
    c, r, s = ells[e]
    ells[e] = (c, r, s * f)
    stats["repairs"] += 1
    stats["max_scale"] = max(stats["max_scale"], f)


def certify(ells: list, simplices: np.ndarray, max_depth: int, patch=None, max_grow: float = np.inf) -> tuple[list, dict]:
    """Grow ellipsoids until every simplex lies in one of them; returns (ellipsoids, stats).

    See the module docstring for the argument. A simplex vertex outside every ellipsoid is repaired
    at once (no bisection can help it); a simplex whose vertices are covered by different
    ellipsoids is bisected, and repaired as a whole at ``max_depth``. ``stats``: simplices checked,
    repairs made, the largest scale-up factor applied.
    """
    ells = [(c, r, s.copy()) for c, r, s in ells]
    stats = {"checked": 0, "repairs": 0, "max_scale": 1.0}
    todo, depth = simplices, 0
    while len(todo):
        stats["checked"] += len(todo)
        m = todo.shape[1]
        flat = todo.reshape(-1, 3)
        maha = np.stack([mahalanobis(flat, *e) for e in ells], axis=1)  # (K*m, E)
        inside = (maha.reshape(-1, m, len(ells)).max(axis=1) <= 1.0).any(axis=1)  # (K,)
        todo = todo[~inside]
        if not len(todo):
            break
        vmin = maha.min(axis=1).reshape(-1, m)[~inside]  # (K', m)
        if (vmin > 1.0).any():
            pts = todo[vmin > 1.0]
            pts = pts[np.argsort(vmin[vmin > 1.0])]
            for x in np.unique(pts, axis=0) if len(pts) < 64 else pts:
                _grow_to(ells, x[None], stats, patch, max_grow)
            continue
        if depth >= max_depth:
            for simp in todo:
                _grow_to(ells, simp, stats, patch, max_grow)
            continue
        todo = _bisect(todo)
        depth += 1
    return ells, stats


# --------------------------------------------------------------------------- one link


def fit_link_cover(polys: list, cfg: FitConfig) -> tuple[list, dict]:
    """Ellipsoids [(c, R, s), ...] (link frame) covering a link's mesh/box elements + fit stats."""
    cfg = cfg.validate()
    rng = np.random.default_rng(cfg.seed)
    solids = solids_of(polys)
    volume = float(sum(m.volume for m in solids))  # overlaps between elements counted twice
    extent = float(np.max([np.ptp(m.bounds, axis=0).max() for m in solids]))
    pitch = cfg.pitch or float(np.clip(extent / 80.0, 5e-4, 3e-3))
    dist = OutsideDistance(solids, pitch, cfg.reach + 3 * pitch)
    surf, interior = sample_solids(solids, cfg.n_points, rng)
    verts = np.concatenate([np.asarray(m.vertices) for m in solids])
    targets = np.concatenate([surf, interior, verts])
    limit = cfg.reach - 2.0 * pitch
    t0 = time.time()
    cands = candidates(targets, dist, limit, rng, cfg.n_seeds, cfg.n_cuts)
    t1 = time.time()
    band = (~dist.occ) & (dist.dist.reshape(-1) <= cfg.reach)
    chosen = greedy_cover(cands, targets, dist.centres[band], pitch**3, volume, cfg)
    from scipy.spatial import cKDTree

    tree = cKDTree(targets)
    dirs = sphere_points(400)
    for _ in range(3):  # small candidates around target points the cover missed
        covered = np.zeros(len(targets), dtype=bool)
        for e in chosen:
            covered |= mahalanobis(targets, *e) <= 1.0
        if covered.all():
            break
        miss = targets[~covered]
        for seed in miss[_fps(miss, 8, rng)]:
            for frac in (0.01, 0.03, 0.07):
                _, nb = tree.query(seed, k=max(8, int(frac * len(targets))))
                cands += _variants(targets[nb], dist, limit, dirs, targets)
        chosen = greedy_cover(cands, targets, dist.centres[band], pitch**3, volume, cfg)
    if not chosen:
        chosen = [mvee(targets)]
    t2 = time.time()
    simp = [simplices_of(m) for m in solids]
    solid_cert = all(full for _, full in simp)
    ells = chosen
    stats: dict[str, Any] = {"checked": 0, "repairs": 0, "max_scale": 1.0}
    k_patch = max(12, len(targets) // 100)

    def patch(pts):  # a small ellipsoid around a gap: the MVEE of it and its nearest target points
        _, nb = tree.query(pts.mean(axis=0), k=k_patch)
        return mvee(np.concatenate([pts, targets[nb]]), tol=1e-2)

    for (s, _) in simp:
        ells, st = certify(ells, s, cfg.max_depth, patch, cfg.max_grow)
        stats["patches"] = stats.get("patches", 0) + st.get("patches", 0)
        stats["checked"] += st["checked"]
        stats["repairs"] += st["repairs"]
        stats["max_scale"] = max(stats["max_scale"], st["max_scale"])
    ells = [(c, r, s * (1.0 + CONTAIN_EPS)) for c, r, s in ells]
    stats.update(t_cand=t1 - t0, t_greedy=t2 - t1, t_cert=time.time() - t2)
    stats.update(n_candidates=len(cands), pitch=pitch, certificate="solid" if solid_cert else "surface")
    return ells, stats
