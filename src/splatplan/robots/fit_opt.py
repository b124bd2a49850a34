"""Tight and safe link models by optimisation: a few ellipsoids per link, placed by gradient descent.

The greedy cover (:mod:`splatplan.robots.fit_cover`) picks from fixed candidates and leaves gaps
that its certificate then closes with centimetres of growth. Here k ellipsoids per link (k small,
3..6 by default) move freely and are optimised together (torch, CPU):

1. **Targets.** The link's solids (:func:`~splatplan.robots.solids.solids_of`), normalised to
   unit size: target points are surface samples, interior samples, the vertices and the edge midpoints. An occupancy
   grid (pitch ``OptConfig.pitch``) gives a signed distance field (Euclidean distance transforms of
   the outside and the inside; > 0 outside), read by trilinear interpolation.
2. **Objective.** Ellipsoid j is ``|A_j (x - c_j)|^2 <= 1`` (A_j any invertible 3x3 matrix).
   Minimised by Adam:

   * the union's volume outside the solid, through its exact gradient: each ellipsoid's surface
     is sampled (``SURFACE_SAMPLES`` points of a Fibonacci lattice mapped by ``c_j + A_j^-1 u``),
     and a sample that is exposed (outside every other ellipsoid and outside the solid) contributes
     ``(n . x) dA`` with its outward normal n and area dA held constant
     (:func:`exposed_volume_surrogate`): the gradient of that sum is the shape derivative of the
     exposed volume (moving an exposed patch outwards by dt adds dt dA). Version 1 counted sampled
     grid cells with a sigmoid instead; its gradient came from the few cells near an ellipsoid's
     boundary and was noisy, and Adam then stalled (``benchmarks/fit_frontier.py``);
   * a hinge on coverage, with a weight that grows: every target point must have
     ``min_j r_j(x) <= 1 - OptConfig.margin`` (all targets every step; the surface is sampled
     densely, since gaps between samples are what the certificate would have to repair by growing
     an ellipsoid);
   * a hinge on reach: the same surface samples must lie within ``OptConfig.reach - pitch`` of the
     solid (field value), with a weight that grows too.

   Adam, learning rate decaying 10x.

   Initialisation: k-means of interior points (``SEED_POINTS``); each cluster's covariance
   ellipsoid (a uniform solid ellipsoid has covariance s^2 / 5 per axis); ``OptConfig.restarts``
   seeds, the best certified result (reach first, then volume) is kept. (Clusters of surface
   points start as flat patches that must grow inwards: with more ellipsoids that fitted worse.)
3. **Certificate** (unchanged, :func:`~splatplan.robots.fit_cover.certify`): every solid is split
   into tetrahedra from a centre point; each must lie in ONE ellipsoid (its 4 vertices inside
   suffice, by convexity), otherwise it is bisected, and at the depth limit the ellipsoid needing
   the least uniform scale-up grows to hold it. The optimised union already contains every target
   point with the margin, so the repairs are small; the reach and the volume are then measured
   by Monte Carlo with exact distances (:mod:`splatplan.robots.fit_measure`), not trusted from
   the objective.
4. **Count per link.** Every k in [``OptConfig.min_per_link``, ``OptConfig.max_per_link``] is
   fitted, certified and measured. With a robot-wide budget (``OptConfig.budget_per_link`` x the
   links, the default) :func:`splatplan.robots.fit.fit_model` shares it between the links
   (:func:`allocate`: each starts at its fewest ellipsoids within reach, the rest goes where it
   removes the most volume per ellipsoid). Without one, a link stops at the first k that meets
   ``OptConfig.volume_ratio`` and ``OptConfig.reach``, else keeps the best volume ratio among the
   k within reach, else the smallest reach.

**Guarantee.** Containment is the certificate's (see :mod:`splatplan.robots.fit_cover`): exact for
star-shaped solids (all Panda links), up to float rounding covered by ``CONTAIN_EPS``. Reach and
volume are measured and reported per link, never guaranteed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._config import bounded, check_config
from .ellipsoid import CONTAIN_EPS, sphere_points
from .fit_cover import certify
from .fit_measure import measure_link
from .solids import occupancy_grid, sample_solids, simplices_of, solids_of

#: Version of the optimising fitter: part of the fit cache key (bump when results change).
OPT_VERSION = 2

#: Surface samples for the coverage term, per target point (dense: gaps between samples are what
#: the certificate must repair by growing ellipsoids).
SURFACE_DENSITY_FACTOR = 8
#: Interior points the k-means start clusters (a start from surface points gives flat patches on
#: the surface that must then grow inwards; more ellipsoids then fit worse, not better).
SEED_POINTS = 4000
#: Samples on each ellipsoid's surface (Fibonacci lattice): the volume gradient and the reach term.
SURFACE_SAMPLES = 600




@dataclass(frozen=True)
class OptConfig:
    """Knobs of the optimising fitter (lengths in metres)."""

    #: Largest distance the model may reach beyond the link's solid (target; measured after the fit).
    reach: float = bounded(0.015, gt=0, le=1.0)
    #: Target union volume / solid volume per link: without a budget, k grows until the measured
    #: fit meets it (and reach).
    volume_ratio: float = bounded(1.3, gt=1.0, le=100.0)
    #: Fewest ellipsoids per link (k starts here).
    min_per_link: int = bounded(3, ge=1, le=32)
    #: Most ellipsoids per link (k stops here even when the targets are missed).
    max_per_link: int = bounded(6, ge=1, le=32)
    #: Target points per link (surface + interior samples).
    n_points: int = bounded(2000, ge=100, le=100_000)
    #: Adam steps per restart.
    steps: int = bounded(1000, ge=10, le=20_000)
    #: Restarts per k (different k-means seeds); the best certified fit is kept.
    restarts: int = bounded(1, ge=1, le=32)
    #: Coverage margin: every target point must reach min_j |A_j (x - c_j)|^2 <= 1 - margin.
    margin: float = bounded(0.01, ge=0, lt=0.5)
    #: Grid pitch of the signed distance field (0: extent / 110, clipped to [0.5, 3] mm).
    pitch: float = bounded(0.0, ge=0, le=0.1)
    #: Longest-edge bisections per tetrahedron in the certificate before an ellipsoid grows.
    max_depth: int = bounded(14, ge=0, le=30)
    #: Robot-wide budget, as the mean ellipsoids per fitted link (the Panda's 11 links: 39); every k
    #: in [min_per_link, max_per_link] is fitted and measured per link, then the links share the
    #: budget (:func:`allocate`: each starts at its fewest ellipsoids within reach, the rest goes
    #: where it removes the most volume per ellipsoid). 0 = no budget: each link keeps its best
    #: volume within reach
    budget_per_link: float = bounded(3.6, ge=0, le=32)
    #: Seed of every random choice (the fit is deterministic for a given seed and torch build).
    seed: int = bounded(0, ge=0, le=2**32 - 1)

    def validate(self) -> "OptConfig":
        check_config(self)
        if self.min_per_link > self.max_per_link:
            from ..errors import SplatplanError

            raise SplatplanError(f"fit min_per_link ({self.min_per_link}) must be <= max_per_link ({self.max_per_link})")
        return self


class SignedField:
    """Signed distance to a union of solids on a grid (> 0 outside, < 0 inside; error ~ one pitch)."""

    def __init__(self, solids: list, pitch: float, margin: float):
        from scipy.ndimage import distance_transform_edt

        self.lo, self.pitch, self.shape, _, occ = occupancy_grid(solids, pitch, margin, min_cells=2)
        # centre-to-centre distances overshoot the surface by about half a pitch on either side
        out, inn = distance_transform_edt(~occ, sampling=pitch), distance_transform_edt(occ, sampling=pitch)
        self.sdf = np.where(occ, 0.5 * pitch - inn, out - 0.5 * pitch)  # (X, Y, Z) m, > 0 outside


def field_at(grid, lo, pitch: float, pts):
    """Trilinear lookup of a voxel-centre grid (X, Y, Z) (torch) at points (N, 3) (torch, same frame as
    ``lo``, the grid's lower corner), differentiable in the points. Beyond the outermost voxel
    centres the value at the nearest one plus the distance to it (a distance field stays 1-Lipschitz)."""
    import torch

    shape = torch.tensor(grid.shape, dtype=pts.dtype)
    idx = (pts - lo) / pitch - 0.5  # (N, 3) voxel-centre coordinates
    inside = torch.minimum(torch.maximum(idx, torch.zeros_like(idx)), shape - 1.0)
    off = torch.linalg.norm(idx - inside, dim=-1) * pitch  # distance beyond the outermost centres
    g = 2.0 * inside / (shape - 1.0) - 1.0  # grid_sample's [-1, 1]; its x indexes the last axis
    v = torch.nn.functional.grid_sample(grid[None, None], g.flip(-1).reshape(1, 1, 1, -1, 3), align_corners=True)
    return v.reshape(-1) + off


def _field_at_numpy(grid: np.ndarray, lo: np.ndarray, pitch: float, pts: np.ndarray) -> np.ndarray:
    """Slow reference of :func:`field_at` (scipy's trilinear interpolator)."""
    from scipy.interpolate import RegularGridInterpolator

    axes = [lo[i] + pitch * (np.arange(grid.shape[i]) + 0.5) for i in range(3)]
    hi = np.array([a[-1] for a in axes])
    clamped = np.clip(pts, lo + 0.5 * pitch, hi)
    return RegularGridInterpolator(axes, grid)(clamped) + np.linalg.norm(pts - clamped, axis=1)


def _kmeans(pts: np.ndarray, k: int, rng: np.random.Generator, iters: int = 30) -> np.ndarray:
    """(N,) cluster labels of k-means (k-means++ seeding)."""
    seeds = [pts[rng.integers(len(pts))]]
    for _ in range(k - 1):
        d = np.min(((pts[:, None] - np.array(seeds)[None]) ** 2).sum(-1), axis=1)
        seeds.append(pts[rng.choice(len(pts), p=d / d.sum())])
    c = np.array(seeds)
    for _ in range(iters):
        lab = np.argmin(((pts[:, None] - c[None]) ** 2).sum(-1), axis=1)
        c = np.array([pts[lab == j].mean(axis=0) if (lab == j).any() else c[j] for j in range(k)])
    return lab


def _init(pts: np.ndarray, k: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Centres (k, 3) and matrices A (k, 3, 3) from the covariance of k-means clusters."""
    lab = _kmeans(pts, k, rng)
    cs, As = [], []
    for j in range(k):
        p = pts[lab == j]
        if len(p) < 4:
            p = pts[rng.choice(len(pts), 16)]
        c = p.mean(axis=0)
        cov = np.cov((p - c).T) + 1e-6 * np.eye(3)
        lam, vec = np.linalg.eigh(cov)
        s = np.sqrt(5.0 * lam)  # a uniform solid ellipsoid: variance s^2 / 5 per axis
        cs.append(c)
        As.append(np.diag(1.0 / s) @ vec.T)
    return np.array(cs), np.array(As)


def optimise(targets, seeds, solid_volume, sdf_grid, lo, pitch, k, cfg: OptConfig, rng, limit) -> list:
    """One restart: k ellipsoids [(c, R, s), ...] in the frame of ``targets`` (normalised units);
    ``seeds`` (M, 3) are the interior points the k-means start clusters, ``solid_volume`` the
    solid's volume in the same units."""
    try:
        import torch
    except ImportError:
        from ..errors import SplatplanError

        raise SplatplanError("fit method 'opt' needs torch (pip install 'splatplan[fit]'); or fit with method 'split' / 'cover'") from None

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # tiny tensors: one thread is fastest; restored below
    try:
        return _optimise(torch, targets, seeds, solid_volume, sdf_grid, lo, pitch, k, cfg, rng, limit)
    finally:
        torch.set_num_threads(threads)


def exposed_volume_surrogate(torch, c, a, dirs, x, field_d, dirs_area: float):
    """A function of the ellipsoids whose gradient is that of the union's volume outside the solid.

    ``x`` (k, U, 3) = c_j + A_j^-1 u are the ellipsoids' surface samples for unit vectors ``dirs``
    (U, 3) (with gradient), ``field_d`` (k, U) their signed distance to the solid (> 0 outside).
    Returns sum over exposed samples (outside every other ellipsoid and outside the solid) of
    (n . x) dA, with the outward unit normal n (along A^T u) and the sample's area dA
    (|det A^-1| |A^T u| times the unit sphere's area per sample, ``dirs_area``) held constant: its
    gradient is the shape derivative, moving an exposed patch outwards by dt adds dt dA of volume.
    """
    k = x.shape[0]
    with torch.no_grad():
        nrm = torch.einsum("kji,uj->kui", a, dirs)  # (k, U, 3) A^T u
        nn = torch.linalg.norm(nrm, dim=-1, keepdim=True)
        area = torch.abs(torch.linalg.det(torch.linalg.inv(a)))[:, None] * nn[..., 0] * dirs_area  # (k, U)
        rx = (torch.einsum("iab,jiub->jiua", a, x[:, None, :, :] - c[None, :, None, :]) ** 2).sum(-1)  # (j, i, U): r_i at x_j,u
        rx = rx.masked_fill(torch.eye(k, dtype=torch.bool)[:, :, None], 2.0)  # its own surface does not hide a sample
        weight = ((rx.min(dim=1).values > 1.0) & (field_d > 0)) * area  # (k, U)
        n_hat = nrm / nn
    return (weight * (n_hat * x).sum(-1)).sum()


def _optimise(torch, targets, seeds, solid_volume, sdf_grid, lo, pitch, k, cfg, rng, limit) -> list:
    c0, a0 = _init(seeds, k, rng)
    dt = torch.float64
    c = torch.tensor(c0, dtype=dt, requires_grad=True)
    a = torch.tensor(a0, dtype=dt, requires_grad=True)
    tg = torch.tensor(targets, dtype=dt)  # (N, 3) every target, every step
    dirs = torch.tensor(sphere_points(SURFACE_SAMPLES), dtype=dt)  # (U, 3)
    dirs_area = 4.0 * np.pi / len(dirs)
    grid = torch.tensor(sdf_grid, dtype=dt)
    lo_t = torch.tensor(lo, dtype=dt)
    opt = torch.optim.Adam([c, a], lr=0.01)
    n = cfg.steps
    for it in range(n):
        frac = it / max(n - 1, 1)
        w_cov = 10.0 * 10.0 ** (5.0 * frac)
        w_reach = 100.0 * 10.0 ** (3.0 * frac)
        for gr in opt.param_groups:
            gr["lr"] = 0.01 * (1.0 - 0.9 * frac)
        opt.zero_grad()
        ainv = torch.linalg.inv(a)  # (k, 3, 3)
        surf = c[:, None, :] + torch.einsum("kij,uj->kui", ainv, dirs)  # (k, U, 3)
        d = field_at(grid, lo_t, pitch, surf.reshape(-1, 3)).reshape(k, -1)  # (k, U) > 0 outside the solid
        vol = exposed_volume_surrogate(torch, c, a, dirs, surf, d.detach(), dirs_area) / solid_volume
        rt = (torch.einsum("kij,nkj->nki", a, tg[:, None, :] - c[None]) ** 2).sum(-1)  # (N, k)
        cov = torch.relu(rt.min(dim=1).values - (1.0 - cfg.margin)).mean() * 30.0  # coverage hinge
        reach = (torch.relu(d - limit) ** 2).mean() / pitch**2
        loss = vol + w_cov * cov + w_reach * reach
        loss.backward()
        opt.step()
    c_np = c.detach().numpy()
    a_np = a.detach().numpy()
    out = []
    for j in range(k):
        _, sv, vt = np.linalg.svd(a_np[j])  # A = U S V^T: |A (x - c)| = |S V^T (x - c)|
        r = vt.T
        if np.linalg.det(r) < 0:
            r[:, 2] *= -1.0
        out.append((c_np[j], r, 1.0 / sv))
    return out


def allocate(options: dict, budget: int, reach: float) -> dict:
    """Share a robot-wide ellipsoid budget between links.

    Args:
        options: link -> [(n ellipsoids, excess volume m^3 (model union minus the solid), reach m), ...],
            one entry per fitted count.
        budget: most ellipsoids in total.
        reach: the reach target (m).
    Returns:
        link -> index of the chosen entry. Each link starts at its fewest ellipsoids among the
        entries within ``reach`` (none within: the entry with the smallest reach); while the budget
        allows, the link whose larger entry (still within reach) removes the most excess volume per
        added ellipsoid moves up. A start that already exceeds the budget is kept (nothing is
        dropped to meet it).
    """
    good, pick = {}, {}
    for link, opts in options.items():
        ok = [i for i, o in enumerate(opts) if o[2] <= reach] or [min(range(len(opts)), key=lambda i: (opts[i][2], opts[i][0]))]
        good[link] = ok
        pick[link] = min(ok, key=lambda i: (opts[i][0], opts[i][1]))
    total = sum(options[link][i][0] for link, i in pick.items())
    while True:
        best = None
        for link, ok in good.items():
            n0, ex0, _ = options[link][pick[link]]
            for i in ok:
                n, ex, _ = options[link][i]
                if n > n0 and ex < ex0 and total + n - n0 <= budget:
                    gain = (ex0 - ex) / (n - n0)
                    if best is None or gain > best[0]:
                        best = (gain, link, i, n - n0)
        if best is None:
            return pick
        _, link, i, dn = best
        pick[link] = i
        total += dn


def fit_link_opt(polys: list, cfg: OptConfig | None = None, k: int | None = None) -> tuple[list, dict]:
    """Ellipsoids [(c, R, s), ...] (link frame) certified to contain a link's mesh/box elements + stats.

    ``k`` fixes the count; by default it grows from ``min_per_link`` as the module docstring says.
    """
    cfg = (cfg or OptConfig()).validate()
    solids = solids_of(polys)
    volume = float(sum(m.volume for m in solids))
    lo_b = np.min([m.bounds[0] for m in solids], axis=0)
    hi_b = np.max([m.bounds[1] for m in solids], axis=0)
    extent = float(np.max(hi_b - lo_b))
    pitch = cfg.pitch or float(np.clip(extent / 110.0, 5e-4, 3e-3))
    t0 = time.time()
    field = SignedField(solids, pitch, cfg.reach + 4 * pitch)
    rng = np.random.default_rng(cfg.seed)
    surf, interior = sample_solids(solids, cfg.n_points, rng)
    dense, _ = sample_solids(solids, 2 * SURFACE_DENSITY_FACTOR * cfg.n_points, rng)  # the surface, densely
    _, seeds = sample_solids(solids, 2 * SEED_POINTS, rng)  # interior points for the k-means start
    verts = np.concatenate([np.asarray(m.vertices) for m in solids])
    edges = np.concatenate([np.asarray(m.vertices)[m.edges_unique].mean(axis=1) for m in solids])
    targets = np.concatenate([surf, interior, verts, edges, dense])
    mu, S = 0.5 * (lo_b + hi_b), extent
    simp_full = [simplices_of(m) for m in solids]
    solid_cert = all(full for _, full in simp_full)
    simp = [sp for sp, _ in simp_full]
    limit = cfg.reach - pitch  # the field's error is about half a pitch; the certificate adds a little
    t1 = time.time()
    tried = []
    ks = [k] if k else list(range(cfg.min_per_link, cfg.max_per_link + 1))
    for kk in ks:
        best = None
        for r in range(cfg.restarts):
            sub = np.random.default_rng([cfg.seed, kk, r])
            e = optimise((targets - mu) / S, (seeds - mu) / S, volume / S**3, field.sdf / S, (field.lo - mu) / S, pitch / S, kk,
                         cfg, sub, limit / S)  # fmt: skip
            e = [(mu + S * c, rot, S * s) for c, rot, s in e]
            grow = 1.0
            for sp in simp:
                e, st = certify(e, sp, cfg.max_depth)
                grow = max(grow, st["max_scale"])
            e = [(c, rot, s * (1.0 + CONTAIN_EPS)) for c, rot, s in e]
            m = measure_link(e, polys, n_samples=4000, n_surface=400, seed=1)
            score = (max(m.reach_m - cfg.reach, 0.0) * 100.0, m.volume_ratio)
            if best is None or score < best[0]:
                best = (score, e, m, grow)
        assert best is not None  # (restarts >= 1)
        tried.append((kk, best[1], best[2], best[3]))
        if best[2].reach_m <= cfg.reach and best[2].volume_ratio <= cfg.volume_ratio and not cfg.budget_per_link:
            break  # (with a robot budget every k is kept: fit_model chooses across links)
    ok = [t for t in tried if t[2].reach_m <= cfg.reach]
    pick = min(ok, key=lambda t: t[2].volume_ratio) if ok else min(tried, key=lambda t: t[2].reach_m)
    stats = {"k": pick[0], "t_setup": t1 - t0, "t_opt": time.time() - t1, "pitch": pitch,
             "certificate": "solid" if solid_cert else "surface",
             # per k tried: (k, measured volume ratio, measured reach m, largest certificate scale-up)
             "tried": [(t[0], t[2].volume_ratio, t[2].reach_m, t[3]) for t in tried],
             # every k tried, for a robot-wide budget (fit_model): (k, ellipsoids, volume ratio, reach m)
             "candidates": [(t[0], t[1], t[2].volume_ratio, t[2].reach_m) for t in tried],
             "solid_volume": volume}  # m^3, what the volume ratios are measured against
    return pick[1], stats
