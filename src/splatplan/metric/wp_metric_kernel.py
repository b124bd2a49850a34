"""Warp kernels of the CollisionSplatting metric (SPEC section 2). Glue lives in :mod:`.wp_metric`.

One thread per query ellipsoid; all accumulators live in registers; no (queries x splats) buffer.

Splats are stored in *tiers* by their largest standard deviation. Tier ``j`` owns the contiguous
index range ``[tier_offset[j], tier_offset[j] + tier_count[j])`` of the splat arrays, a hash grid
``tier_grid[j]`` over those means (indices returned by the grid are local to the tier) and
``tier_sigma[j]`` = the largest std of any splat in it. The last tier may be a 1x1x1 grid: every
query then visits all of its points (the exhaustive set for huge splats).

Exactness (the query is conservative: it never misses a splat with s2~ < cap but may visit
extra candidates, which the distance test removes). With s = sqrt(s2), |grad s2| <= 2 s / a_min
and sigma <= sigma_g |grad s2|, so s2~ >= s^2 - 2 k s with k = n_sigma sigma_g / a_min. Hence
s2~ >= cap whenever s >= k + sqrt(k^2 + cap), and since s >= |d| / a_max every splat farther than
rho = a_max (k + sqrt(k^2 + cap)) has s2~ >= cap. The tier radius below uses that rho (times a
relative slack of 1e-4 against float32 rounding).
"""

from __future__ import annotations

from .._warp import wp as _wp

wp = _wp()

RHO_SLACK = 1.0001
# Softmin terms exp(-t (v - pivot)) below exp(-20) ~ 2e-9 are skipped: the sum (>= 1) changes by
# less than N * 2e-9 relative, so the softmin moves by < N * 2e-9 / t (1e-7 for N = 500, t = 10).
SOFTMIN_SKIP = wp.constant(20.0)


@wp.func
def tier_radius(n_sigma: float, sigma_g: float, a_min: float, a_max: float, cap: float):
    """rho = a_max (k + sqrt(k^2 + cap)), k = n_sigma sigma_g / a_min: splats beyond have s2~ >= cap."""
    k = n_sigma * sigma_g / a_min
    return a_max * (k + wp.sqrt(k * k + cap)) * RHO_SLACK


@wp.func
def conservative_s2(d: wp.vec3, link_a: wp.mat33, m: wp.mat33, n_sigma: float):
    """s2~ = max(0, d^T A d - n_sigma |diag(s) R^T (2 A d)|) for splat offset d = mu - c."""
    ad = link_a * d
    s2 = wp.dot(d, ad)
    sigma = wp.length(m * (2.0 * ad))
    return wp.max(0.0, s2 - n_sigma * sigma)


@wp.func
def link_s2(d: wp.vec3, dd: float, link_a: wp.mat33, sphere: bool, inv_r2: float, m: wp.mat33, n_sigma: float):
    """s2~ of one splat; for a sphere link (A = I / r^2, so A d = d / r^2) it reuses dd = |d|^2."""
    if sphere:
        return wp.max(0.0, (dd - n_sigma * 2.0 * wp.length(m * d)) * inv_r2)
    return conservative_s2(d, link_a, m, n_sigma)


@wp.kernel
def metric_full_kernel(
    offset: int,  # first query handled by this launch (CPU launches split the batch)
    centers: wp.array(dtype=wp.vec3),  # (B,) link centres, world frame
    link_a: wp.array(dtype=wp.mat33),  # (B,) A = R diag(1/a^2, 1/b^2, 1/c^2) R^T
    axis_minmax: wp.array(dtype=wp.vec2),  # (B,) (a_min, a_max) semi-axes
    means: wp.array(dtype=wp.vec3),  # (N,) splat means, tier-sorted
    mrows: wp.array(dtype=wp.mat33),  # (N,) diag(s) R^T per splat
    tier_grid: wp.array(dtype=wp.uint64),  # (T,) hash-grid ids
    tier_offset: wp.array(dtype=wp.int32),  # (T,)
    tier_sigma: wp.array(dtype=wp.float32),  # (T,) largest std in the tier
    n_tiers: int,
    n_sigma: float,
    cap: float,  # s2_cap: exactness threshold and neighbourhood N(q) = {s2~ < cap}
    softmin_t: float,
    d_max: float,
    gamma: float,
    s_min: float,
    reduce_code: int,  # 0 mean, 1 sum, 2 max
    pow_m: int,  # > 0 when softmin_t == pow_m * gamma (softmin terms from the cost's exp), else 0
    out_min: wp.array(dtype=wp.float32),  # (B,)
    out_ncol: wp.array(dtype=wp.int32),  # (B,)
    out_softmin: wp.array(dtype=wp.float32),  # (B,)
    out_cost: wp.array(dtype=wp.float32),  # (B,)
):
    q = wp.tid() + offset
    c = centers[q]
    a = link_a[q]
    mm = axis_minmax[q]

    best = float(wp.inf)  # min s2~ over visited splats
    ncol = int(0)  # splats with s2~ < 1
    pivot = float(wp.inf)  # running minimum of s2~ over N(q) (softmin pivot)
    acc = float(0.0)  # sum exp(-t (s2~ - pivot)) over N(q)
    n_nb = int(0)  # |N(q)|
    c_sum = float(0.0)
    c_max = float(0.0)
    pg = float(1.0)  # exp(gamma (pivot - s_min)), updated with the pivot
    sphere = mm[0] == mm[1]  # A = I / r^2: cheaper s2~
    inv_r2 = 1.0 / (mm[0] * mm[0])

    for j in range(n_tiers):
        rho = tier_radius(n_sigma, tier_sigma[j], mm[0], mm[1], cap)
        rho2 = rho * rho
        base = tier_offset[j]
        query = wp.hash_grid_query(tier_grid[j], c, rho)
        local = int(0)
        while wp.hash_grid_query_next(query, local):
            i = base + local
            d = means[i] - c
            dd = wp.dot(d, d)
            if dd <= rho2:
                v = link_s2(d, dd, a, sphere, inv_r2, mrows[i], n_sigma)
                best = wp.min(best, v)
                if v < 1.0:
                    ncol += 1
                if v < cap:
                    n_nb += 1
                    eg = wp.exp(-gamma * (v - s_min))  # the one exp per neighbour in the common case
                    cv = d_max * wp.min(eg, 1.0)  # d_max exp(-gamma max(v - s_min, 0))
                    if v < pivot:
                        acc = acc * wp.exp(-softmin_t * (pivot - v)) + 1.0
                        pivot = v
                        pg = wp.exp(gamma * (pivot - s_min))  # eg * pg = exp(-gamma (v - pivot))
                    elif pow_m > 0:
                        # t = m gamma: exp(-t (v - pivot)) = (eg * pg)^m, no second exp
                        e = eg * pg
                        term = e
                        for _k in range(pow_m - 1):
                            term = term * e
                        acc += term
                    elif softmin_t * (v - pivot) < SOFTMIN_SKIP:
                        acc += wp.exp(-softmin_t * (v - pivot))
                    c_sum += cv
                    c_max = wp.max(c_max, cv)

    out_min[q] = best
    out_ncol[q] = ncol
    if n_nb > 0:
        out_softmin[q] = pivot - wp.log(acc) / softmin_t
        if reduce_code == 0:
            out_cost[q] = c_sum / float(n_nb)
        elif reduce_code == 1:
            out_cost[q] = c_sum
        else:
            out_cost[q] = c_max
    else:
        out_softmin[q] = float(wp.inf)
        out_cost[q] = 0.0


@wp.kernel
def metric_collide_kernel(
    offset: int,
    centers: wp.array(dtype=wp.vec3),  # (B,)
    link_a: wp.array(dtype=wp.mat33),  # (B,)
    axis_minmax: wp.array(dtype=wp.vec2),  # (B,)
    means: wp.array(dtype=wp.vec3),  # (N,)
    mrows: wp.array(dtype=wp.mat33),  # (N,)
    tier_grid: wp.array(dtype=wp.uint64),  # (T,)
    tier_offset: wp.array(dtype=wp.int32),  # (T,)
    tier_sigma: wp.array(dtype=wp.float32),  # (T,)
    n_tiers: int,
    n_sigma: float,
    k_collide: int,  # in collision when more than k splats have s2~ < 1
    out_hit: wp.array(dtype=wp.int32),  # (B,) 1 in collision, 0 free
):
    """Collision-only variant: radius for cap = 1, stops at the (k+1)-th colliding splat."""
    q = wp.tid() + offset
    c = centers[q]
    a = link_a[q]
    mm = axis_minmax[q]
    ncol = int(0)
    sphere = mm[0] == mm[1]
    inv_r2 = 1.0 / (mm[0] * mm[0])
    j = int(0)
    while j < n_tiers and ncol <= k_collide:
        rho = tier_radius(n_sigma, tier_sigma[j], mm[0], mm[1], 1.0)
        rho2 = rho * rho
        base = tier_offset[j]
        query = wp.hash_grid_query(tier_grid[j], c, rho)
        local = int(0)
        while ncol <= k_collide and wp.hash_grid_query_next(query, local):
            i = base + local
            d = means[i] - c
            dd = wp.dot(d, d)
            if dd <= rho2:
                if link_s2(d, dd, a, sphere, inv_r2, mrows[i], n_sigma) < 1.0:
                    ncol += 1
        j += 1
    out_hit[q] = wp.where(ncol > k_collide, 1, 0)
