"""Slow, obviously-correct numpy reference of the CollisionSplatting metric (float64, brute force).

Every output of the Warp kernel in :mod:`.wp_metric_kernel` has its twin here; tests compare them
on random inputs. Memory is bounded by chunking the queries, never (all queries x all splats).
"""

from __future__ import annotations

import numpy as np

from ..scenes.splats import quat_to_rotmat
from .config import MetricConfig, QueryResult


def search_radius_ref(n_sigma, sigma_g, a_min, a_max, cap) -> np.ndarray:
    """The kernels' search radius (:func:`~.wp_metric_kernel.search_radius`), vectorised in float64:
    rho = a_max (k + sqrt(k^2 + cap)) (1 + 1e-4), k = n_sigma sigma_g / a_min (arguments broadcast).

    The glue evaluates the radius here rather than calling the ``@wp.func`` in Python scope (~40 us a
    call, float32); ``tests/metric/test_properties.py`` checks the two agree."""
    from .wp_metric_kernel import RHO_SLACK

    k = np.asarray(n_sigma, dtype=np.float64) * np.asarray(sigma_g, dtype=np.float64) / np.asarray(a_min, dtype=np.float64)
    return np.asarray(a_max, dtype=np.float64) * (k + np.sqrt(k * k + np.asarray(cap, dtype=np.float64))) * float(RHO_SLACK)


def link_matrices(quats: np.ndarray | None, semi_axes: np.ndarray, batch: int, rots: np.ndarray | None = None) -> np.ndarray:
    """A = R diag(1/a^2, 1/b^2, 1/c^2) R^T per query, float64 (B, 3, 3).

    Args:
        quats: wxyz (B, 4) link orientations in the world frame, or None for identity.
        semi_axes: (3,) or (B, 3) semi-axes (a, b, c) in the link frame, scene units.
        batch: B.
        rots: (B, 3, 3) world <- link rotation matrices, instead of ``quats``.
    """
    w = 1.0 / np.broadcast_to(np.asarray(semi_axes, dtype=np.float64), (batch, 3)) ** 2  # (B, 3)
    if rots is not None:
        r = np.asarray(rots, dtype=np.float64).reshape(batch, 3, 3)
    elif quats is None:
        a = np.zeros((batch, 3, 3))
        a[:, [0, 1, 2], [0, 1, 2]] = w
        return a
    else:
        r = quat_to_rotmat(quats)  # (B, 3, 3)
    return np.matmul(r * w[:, None, :], np.swapaxes(r, 1, 2))  # R diag(w) R^T


def conservative_s2_ref(
    splat_means: np.ndarray,  # (N, 3)
    splat_quats: np.ndarray,  # (N, 4) wxyz
    splat_scales: np.ndarray,  # (N, 3) linear std
    centers: np.ndarray,  # (B, 3)
    link_A: np.ndarray,  # (B, 3, 3)
    n_sigma: float | np.ndarray,  # scalar or per splat (N,)
    linearize: str = "distance",  # MetricConfig.linearize: "distance" or "squared" (the paper)
) -> tuple[np.ndarray, np.ndarray]:
    """(s2, s2~) for every (query, splat) pair, each float64 (B, N). Use on small inputs only.

    ``linearize`` (:attr:`MetricConfig.linearize`): "squared" s2~ = max(0, s2 - n sigma) (the paper),
    "distance" s2~ = max(0, sqrt(s2) - n sigma / (2 sqrt(s2)))^2."""
    d = splat_means[None, :, :].astype(np.float64) - centers[:, None, :].astype(np.float64)  # (B, N, 3)
    ad = np.einsum("bij,bnj->bni", link_A, d)  # A d
    s2 = np.einsum("bni,bni->bn", d, ad)
    g = 2.0 * ad  # gradient of s2 at the splat mean
    rot = quat_to_rotmat(splat_quats)  # (N, 3, 3)
    m = np.einsum("nji,bnj->bni", rot, g) * splat_scales[None].astype(np.float64)  # diag(s) R^T g
    sigma = np.linalg.norm(m, axis=-1)
    ns = np.asarray(n_sigma, dtype=np.float64)
    if linearize == "squared":
        return s2, np.maximum(0.0, s2 - ns * sigma)
    if linearize != "distance":
        raise ValueError(f"linearize must be 'distance' or 'squared', got {linearize!r}")
    t = s2 - 0.5 * ns * sigma  # s * s~: positive exactly when s~ > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        return s2, np.where(t > 0.0, t * t / np.where(s2 > 0.0, s2, 1.0), 0.0)


def splat_inflation_ref(opacities: np.ndarray | None, n: int, config: MetricConfig) -> tuple[np.ndarray, np.ndarray]:
    """(keep (N,) bool, n_sigma per splat (N,)) under the opacity options of ``config``.

    Splats with opacity < ``opacity_min`` are free space (dropped); with ``opacity_scaled_inflation``
    splat i is inflated by n_sigma * o_i.
    """
    o = np.ones(n) if opacities is None else np.asarray(opacities, dtype=np.float64).reshape(n)
    keep = o >= config.opacity_min if config.opacity_min > 0 else np.ones(n, dtype=bool)
    ns = config.n_sigma * o if config.opacity_scaled_inflation else np.full(n, float(config.n_sigma))
    return keep, ns


def softmin_ref(v: np.ndarray, t: float, mode: str = "sum") -> float:
    """-(1/t) log sum exp(-t v) ("sum") or -(1/t) log mean exp(-t v) ("mean"), stable; +inf when empty."""
    if v.size == 0:
        return np.inf
    m = v.min()
    s = m - np.log(np.exp(-t * (v - m)).sum()) / t
    return s + np.log(v.size) / t if mode == "mean" else s


def collision_metric_ref(
    splat_means: np.ndarray,  # (N, 3)
    splat_quats: np.ndarray,  # (N, 4) wxyz
    splat_scales: np.ndarray,  # (N, 3)
    centers: np.ndarray,  # (B, 3)
    quats: np.ndarray | None,  # (B, 4) wxyz or None
    semi_axes: np.ndarray,  # (3,) or (B, 3)
    config: MetricConfig,
    chunk: int = 64,
    opacities: np.ndarray | None = None,  # (N,) needed by the opacity options
    rots: np.ndarray | None = None,  # (B, 3, 3) world <- link, instead of quats
) -> QueryResult:
    """Brute-force reference of all five outputs (see :class:`QueryResult`)."""
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    b = centers.shape[0]
    a_all = link_matrices(quats, semi_axes, b, rots)
    keep, ns = splat_inflation_ref(opacities, len(splat_means), config)
    if not keep.all():
        splat_means, splat_quats, splat_scales, ns = splat_means[keep], splat_quats[keep], splat_scales[keep], ns[keep]
    out = {k: np.empty(b, dtype=np.float64) for k in ("min_s2", "softmin", "cost")}
    ncol = np.empty(b, dtype=np.int64)
    t = config.softmin_t
    for lo in range(0, b, chunk):
        hi = min(b, lo + chunk)
        _, s2t = conservative_s2_ref(splat_means, splat_quats, splat_scales, centers[lo:hi], a_all[lo:hi], ns, config.linearize)
        out["min_s2"][lo:hi] = s2t.min(axis=1) if s2t.shape[1] else np.inf
        ncol[lo:hi] = (s2t < 1.0).sum(axis=1)
        nb = s2t < config.s2_cap  # the neighbourhood N(q)
        for j in range(hi - lo):
            v = s2t[j][nb[j]]
            if v.size == 0:
                out["softmin"][lo + j] = np.inf
                out["cost"][lo + j] = 0.0
                continue
            out["softmin"][lo + j] = softmin_ref(v, t, config.softmin_mode)
            c = config.cost_d_max * np.exp(-config.cost_gamma * np.maximum(v - config.cost_s_min, 0.0))
            out["cost"][lo + j] = {"mean": c.mean, "sum": c.sum, "max": c.max}[config.cost_reduce]()
    return QueryResult(
        min_s2=out["min_s2"],
        n_colliding=ncol,
        in_collision=ncol > config.k_collide,
        softmin=out["softmin"],
        cost=out["cost"],
    )


def mean_distance_lb_ref(lb: np.ndarray, origin: np.ndarray, v: float, box_lo: np.ndarray, box_hi: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The numpy twin of the kernels' ``mean_distance_lb`` (MEAN DISTANCE GRID): for points (P, 3), the
    larger of the distance to the means' box (times 0.999) and the bound stored in the point's voxel
    of ``lb`` (nz, ny, nx) (0 outside the grid); grid arrays as :func:`~.tiers.mean_distance_bounds`
    returns them."""
    p = np.asarray(pts, dtype=np.float64)
    lo, hi = np.asarray(box_lo, dtype=np.float64), np.asarray(box_hi, dtype=np.float64)
    d = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=-1) * 0.999
    inside, val = _voxel_lookup(lb, origin, v, p)
    return np.maximum(d, np.where(inside, val, 0.0))


def _voxel_lookup(grid: np.ndarray, origin: np.ndarray, v: float, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inside (P,) bool, value (P,)): whether each point (P, 3) lies in the voxel grid ``grid``
    (nz, ny, nx) of corner ``origin`` and side ``v``, and its voxel's value (the clamped voxel outside)."""
    dims = np.array(grid.shape[::-1])  # (nx, ny, nz)
    f = (np.asarray(pts, dtype=np.float64) - np.asarray(origin, dtype=np.float64)) / v
    inside = np.all((f >= 0) & (f < dims), axis=-1)
    ijk = np.clip(np.floor(f).astype(np.int64), 0, dims - 1)
    return inside, grid[ijk[..., 2], ijk[..., 1], ijk[..., 0]]


def hit_bound_ref(ub: np.ndarray, origin: np.ndarray, v: float, pts: np.ndarray, a_min: np.ndarray) -> np.ndarray:
    """The numpy twin of the kernels' ``hit_bound`` lookup (HIT BOUND): for points (P, 3) and
    smallest semi-axes (P,), True where the point lies in the grid and its voxel's upper bound ``ub``
    (nz, ny, nx) (:func:`~.tiers.mean_distance_upper`) is below 0.999 a_min."""
    inside, val = _voxel_lookup(ub, origin, v, pts)
    return inside & (val < 0.999 * np.asarray(a_min, dtype=np.float64))


def cover_spheres_ref(center: np.ndarray, rot: np.ndarray, axes: np.ndarray, s_star: float = 1.0, max_spheres: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """The numpy twin of the kernels' COVER SPHERES of one link: K = min(``max_spheres``,
    ceil(2 a1 / a2)) spheres along its longest axis (a1 the longest semi-axis, a2 the second) whose
    union holds the link scaled by ``s_star`` (``center`` (3,), ``rot`` (3, 3) world <- link,
    ``axes`` (3,)). Sphere i covers the slab of axis coordinates [t_i - h, t_i + h] (h = a1 / K); a
    point of the link at axis coordinate x lies within (x - t_i)^2 + a2^2 (1 - x^2 / a1^2) of the
    slab's centre (squared), largest at an end of the slab.

    Returns:
        centres (K, 3) world, radii (K,) (before the kernel's float32 pad); K = 0 where h^2 + a2^2 >=
        a1^2 (a link so close to a sphere that the middle spheres would reach beyond its bounding
        sphere: the kernels do not try a cover there).
    """
    a = np.asarray(axes, dtype=np.float64)
    m = int(np.argmax(a))
    a1 = a[m]
    a2 = float(np.max(np.delete(a, m)))
    k = int(min(max_spheres, np.ceil(2.0 * a1 / a2)))
    h = a1 / k
    if h * h + a2 * a2 >= a1 * a1:  # a near sphere: no cover tighter than its bounding sphere
        return np.zeros((0, 3)), np.zeros(0)
    t = -a1 + h * (2 * np.arange(k) + 1)  # (K,)
    ends = np.stack([np.maximum(t - h, -a1), np.minimum(t + h, a1)])  # (2, K)
    r2 = np.max((ends - t) ** 2 + a2 * a2 * (1.0 - ends**2 / (a1 * a1)), axis=0)  # (K,)
    u = np.asarray(rot, dtype=np.float64)[:, m]
    return np.asarray(center, dtype=np.float64) + np.outer(t * s_star, u), np.sqrt(np.maximum(r2, 0.0)) * s_star


def cell_s2_lb_ref(center: np.ndarray, rot: np.ndarray, axes: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The numpy twin of the kernels' CELL BOXES bound (float64, without the kernel's float32 pad):
    for links (..., 3) centres, (..., 3, 3) world <- link rotations, (..., 3) semi-axes and boxes
    [lo, hi] (..., 3), the lower bound sum_k max(|u_k . (m - c)| - r_k, 0)^2 / a_k^2 on the squared
    scaling distance of every point of the box (u_k the link's axes, m the box centre, r_k the
    half-width of the box's projection on u_k). Returns (...,)."""
    c = np.asarray(center, dtype=np.float64)
    r = np.asarray(rot, dtype=np.float64)
    a = np.asarray(axes, dtype=np.float64)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    m = 0.5 * (lo + hi) - c  # (..., 3)
    half = 0.5 * (hi - lo)  # (..., 3)
    p = np.einsum("...ik,...i->...k", r, m)  # (..., 3) the box centre on each link axis
    w = np.einsum("...ik,...i->...k", np.abs(r), half)  # (..., 3) the box's half-width on each axis
    g = np.maximum(np.abs(p) - w, 0.0)
    return np.sum(g * g / (a * a), axis=-1)
