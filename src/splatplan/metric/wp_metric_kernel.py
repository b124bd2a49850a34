"""Warp kernels of the CollisionSplatting metric (SPEC section 2). Glue lives in :mod:`.wp_metric`.

One thread per query ellipsoid; all accumulators live in registers; no (queries x splats) buffer.
Kernel arguments are three structs: :class:`LinkBatch` (the query ellipsoids, read on the device:
link matrices are built here, not on the host), :class:`SplatTiers` (the scene in one grid set's
memory order) and :class:`MetricParams` (the config), plus the outputs.

Splats are stored in *tiers* (runs of size classes of their largest standard deviation, grouped
per query size by :mod:`.wp_metric`). Tier ``j`` owns
the contiguous index range ``[offset[j], offset[j + 1])`` of the splat arrays, sorted by grid cell
(cell = floor(p / width_j) mod dims_j per axis, the rule of Warp's hash grid), a table
``cell_start`` of where every cell's run of splats begins, and ``sigma[j]`` = the largest std of any
splat in it. A query reads each row of cells (along x) it covers as one contiguous run of splats
(two when the row wraps around), without per-cell hashing. A tier's grid may be 1x1x1: every query then
visits all of its points (the exhaustive set for huge splats).

Exactness (the query is conservative: it never misses a splat with s2~ < cap but may visit
extra candidates, which the distance test removes). With s = sqrt(s2), |grad s2| <= 2 s / a_min
and sigma <= sigma_g |grad s2|, so s2~ >= s^2 - 2 k s with k = n_sigma sigma_g / a_min. Hence
s2~ >= cap whenever s >= k + sqrt(k^2 + cap), and since s >= |d| / a_max every splat farther than
rho = a_max (k + sqrt(k^2 + cap)) has s2~ >= cap. :func:`search_radius` is that rho (times a
relative slack of 1e-4 against float32 rounding); it is the one definition of the formula, used by
the kernels, by the glue (grid cell sizes) and by the tests. The opacity options only shrink the
inflation (o_i <= 1) or drop splats, and the distance linearisation (LINEARISATION below) gives an
s2~ no smaller than the paper's, so the same radius stays exact. The same bound in s, s2 >
(rho / a_max)^2, rejects candidates inside the bounding sphere but far outside an elongated link
before their inflation is computed.

A second bound holds per link axis: with u = diag(1/a) R^T d (so s = |u|) and |A d| = |diag(1/a) u|
<= sum_k |u_k| / a_k, s2~ >= sum_k (u_k^2 - 2 k_k |u_k|) = sum_k (|u_k| - k_k)^2 - K^2 with
k_k = n_sigma sigma_g / a_k and K^2 = sum_k k_k^2; so s2~ < cap implies |u_k| < k_k + sqrt(cap + K^2),
i.e. the link-frame coordinate |e_k| < n_sigma sigma_g + a_k sqrt(cap + K^2) (:func:`link_box`). The
full kernel reads only grid cells within both the ball and (the world box around) that link box,
which is much smaller than the ball for a thin link near big splats.

ROW_CLIP (full kernel). A splat with s2 > s2_cut = (rho / a_max)^2 is rejected anyway, so only the
ellipsoid E = {p : (p - c)^T A (p - c) <= s2_cut} (intersected with the query's ball) can hold
neighbours. For a row of cells (a tube y in [y0, y1], z in [z0, z1]) the x extent of E on the tube
is [c_x + min m - h, c_x + max m + h] with m(dy, dz) = -(A_xy dy + A_xz dz) / A_xx (linear: its extremes
are at the rectangle's corners) and h = sqrt((s2_cut - q_min) / A_xx), q_min the minimum over the
rectangle of the yz Schur complement form q = [dy dz] (A_yz - b b^T / A_xx) [dy dz]^T (convex: 0 inside,
else on an edge, where the 1-D minimiser is clamped); the row is skipped when q_min > s2_cut. The
kernel reads only the cells of that x interval (also clipped to the ball), in rows holding more than
``ROW_CLIP_MIN`` splats and only when no axis's cell range wrapped onto itself (else a cell does not
stand for one unwrapped position). Margins: s2_cut grown by 2% and q_min shrunk by 2%, far above the
float32 error of the Schur complement (about (a_max / a_min)^2 ulps) for links with a_max <= 50 a_min,
the only ones clipped; the cell bounds are padded by 1% of a cell. The set of splats scanned shrinks,
never the set with s2~ < cap, so the outputs are unchanged. It matters for elongated links near dense
surfaces, whose axis-aligned boxes hold ~10x more splats than their ellipsoid (Panda links near the
table: the full query ~1.5x faster). The collision-only kernel clips its rows the same way
(``TierConfig.collide_row_clip``, on by default): measured slower on early versions, where its
candidates were cheap, but it saves 1.4x on robot edge checks, whose configurations are mostly free
and near surfaces (every candidate is read), and 4x on the Panda at Stonehenge's scale 1.

An earlier version also cut elongated links into up to 4 slabs along the long axis, one grid query
each. Once rows were clipped to the ellipsoid, the slabs' overlapping boxes only made splats be read
twice (CPU: Panda rollouts near the table 1.1-1.2x, random 4:1 and 10:1 links 1.4-1.7x faster without
them), so every link is one box now.

Launch position and query index differ when the glue sorts a batch (Morton order of the centres,
``LinkBatch.order``): neighbouring threads then read neighbouring splats; every output is still
written at the query's own index, so results do not depend on the order.

LANES (full kernel, ``LanePartials``). With ``lanes`` > 1 each query has that many adjacent threads:
lane l walks the same tiers and cell rows as every other lane of its query and takes the
splats start + l, start + l + lanes, ... of each cell run, so on a GPU the lanes of a warp read
neighbouring splats and share the control flow (one thread per query leaves a warp waiting for its
busiest query). Each lane writes its partial sums; ``metric_lanes_combine_kernel`` reduces them in
lane order (deterministic) and writes the outputs. Counts, flags and min s2~ equal the one-thread
results; the softmin and cost sums differ only in float summation order.

MEAN DISTANCE GRID (collision-only kernel). A voxel grid over the means' bounding box stores, per
voxel, a lower bound on the distance from any point of the voxel to the nearest mean: the
box-to-box distance to the nearest voxel holding a mean (:func:`~.wp_metric.mean_distance_bounds`),
shrunk by a margin far above float32 rounding. Outside the
grid the bound is the distance to the means' box. A tier whose search radius rho is below the bound
at the query's centre has no splat with ``|d| <= rho``, which the kernel would read, so it is skipped
without reading a cell: the outputs are those of the plain kernel, for every n_sigma (rho already
covers the inflation). A robot edge check is mostly links in free space (MBM Panda: ~98% of the
grown links' checks at tree nodes are farther from every mean than their longest semi-axis), where
this replaces the cell rows by one read.

COVER SPHERES (collision-only kernels, ``TierConfig.collide_cover``). The bound at a link's centre
clears it only when every mean is farther than its longest semi-axis (times s*); an elongated link
beside a surface fails that test although its ellipsoid is far from every mean. Such a link is next
tested by K = min(4, ceil(2 a1 / a2)) spheres along its longest axis (a1 the longest semi-axis, a2
the second): sphere i is centred at axis coordinate t_i = -a1 + h (2 i + 1), h = a1 / K, and holds
the slab of the link with axis coordinate x in [t_i - h, t_i + h], whose points lie within
(x - t_i)^2 + a2^2 (1 - x^2 / a1^2) of its centre (squared; convex in x, so the largest value is
at an end of the slab, which gives its radius). The spheres of the link scaled by s* = k + sqrt(k^2
+ 1), k = n_sigma sigma_top / a_min (sigma_top the largest tier std), hold every mean with s2~ < 1
(the radius bound above, for every tier); when the mean-distance bound at each sphere's centre
exceeds its radius (plus the float32 pads of the group bound), no mean lies in that scaled link and
the link is free without a splat read: the same answer (and FREE SLACK, 0 for a link the centre
bound leaves near). A link so close to a sphere that h^2 + a2^2 >=
a1^2 (its middle spheres would reach beyond its bounding sphere) is not tried. With the RIGID SLACK
and a target > 0, a rigid motion that moves no point of the link farther than delta moves no point
of s* E farther than s* delta, so the link stays free while s* delta is below the smallest (bound
minus radius) over its spheres: that slack is returned when it meets the target, else the link is
scanned as before and keeps the larger slack. MBM Panda (the 45 ellipsoids grown by the margin,
configurations of its planners): ~35% of the links the centre bound leaves near are cleared, free
configurations 7-10% faster (``benchmarks/mbm_speed.py``, near-surface configurations: box 5.7 -> 5.0
us, table_pick and bookshelf within noise); the bound's voxels (2^21 over the scene) limit it: with
exact distances ~80% would be.

CELL BOXES (collision-only kernels, ``TierConfig.collide_cell_boxes``). Each grid cell of a dense
tier (more than ``CELL_BOX_MIN`` splats per occupied cell, boxes no larger than the tier's splat
data) also stores the bounding box of its means. A scan then reads a row's cells one by one and
skips a cell holding more than ``CELL_BOX_MIN`` splats when a lower bound on the squared scaling
distance s2 over its box exceeds the cut s2_cut = (rho / a_max)^2 that every read splat is tested
against: with u_k the link's axes, s2 = sum_k (u_k . d)^2 / a_k^2 >= sum_k (min over the box of
|u_k . d|)^2 / a_k^2, and the minimum of |u_k . d| over a box is the distance from 0 of the box's
projection interval (:func:`cell_s2_lb`; the box grown by 1e-5 (1 + |c|) and the bound shrunk by
0.1% against float32 rounding). A skipped splat has s2 > s2_cut, which the scan rejects (link_s2
returns +inf; with the RIGID SLACK its s2 exceeds the scan's cap, so the smallest s2 below the cap
is unchanged): every output, slack included, is the plain scan's. A surface patch beside a near
link then costs one test instead of its splats. MBM Panda (the planners' own batches replayed,
~70 splats a cell): node checks 5-11% and edge checks with RIGID SLACK 7-10% faster; whole plans
~3% (interleaved, 18 problems; within the noise of one benchmark run); the built-in scenes (17-32
splats a cell) unchanged.

HIT BOUND (collision-only kernels). On the same voxels, a second array stores an upper bound on the
distance from any point of the voxel to the nearest mean that counts (opacity at least
``MeanDistanceGrid.ub_opacity``; :func:`~.tiers.mean_distance_upper`), grown by a margin far above
float32 rounding. A link whose centre reads a bound below ``HIT_SHRINK`` a_min holds such a mean
inside its (plain) ellipsoid: s2 <= |d|^2 / a_min^2 < 1, and s2~ <= s2 for every n_sigma >= 0 and
either linearisation, so that splat collides and, with ``k_collide`` 0, so does the link; it is
reported without a splat read (the scan would find it; same output). The bound is used only when
the splats it counts are a subset of those the test counts (no opacity rule, or ``opacity_min <=
ub_opacity``). The per-configuration kernel checks every near group's members this way before it
scans any (a colliding planner sample usually has a link deep in the geometry: MBM Panda, ~80% of
them end at these reads); a colliding configuration's slack is 0.

FREE SLACK (collision-only kernel, ``want_slack``). A link that exits on the mean-distance bound
gets ``slack = (d_lb - rho) * DIST_SHRINK``, rho its largest tier radius: every mean is farther than
rho from every point within ``slack`` of the centre, so the same link (same semi-axes, any
orientation) with its centre anywhere within ``slack`` of this one's is free too, and the kernel
would read no splat for it. Other links get 0 (nothing proven).

RIGID SLACK (``want_slack`` 2; the slack array holds each query's *target* on input). A weaker
promise that near-surface links can get too: the same link moved rigidly so that no point of it
moves farther than the slack stays free. Per tier j, with k = n_sigma sigma_j / a_min and
s* = k + sqrt(k^2 + 1), every splat whose mean has scaling distance s >= s* has s2~ >= 1 (the radius
bound above: s2~ >= s^2 - 2 k s). The map x -> diag(1/a) R^T (x - c) is 1/a_min-Lipschitz, so a mean
at scaling distance s lies at least a_min (s - s*) from the scaled link s* E; a rigid motion moving
no point of E farther than delta moves no point of s* E farther than s* delta (each point's bound
is |v| + |w| r, and s* E reaches s* times as far from the centre, s* >= 1). Hence the link stays free
while delta < a_min (s_min - s*) / s*, s_min over the tier's means that count (opacity options as
in the test); the link's rigid slack is the smallest over the tiers. A link whose mean-distance slack
above is below its target scans each tier with the cap (s* (1 + lam))^2, lam = min(target / a_min,
RIGID_SLACK_MAX): every mean with s below that root is read (s2~ <= s2 and the scan never misses an
s2~ below its cap; a tier skipped by the mean-distance grid has none), the collision test itself
uses the cap-1 cut, and the slack is the larger of the two. The per-configuration kernel scans a group-bound
member the same way when its group slack falls short of its target; it also keeps the smallest
slack / target ratio of the links done so far and asks later links for only that share of their
targets (a planner proves samples with the smallest ratio: a larger one reads splats for nothing). Robot edge checks use the
rigid slack to skip check samples that are proven free (:class:`~splatplan.planners.edges.EdgeChecker`),
with a point-motion bound per ellipsoid.

LINEARISATION (``MetricParams.lin_distance``). With g = |diag(s) R^T A d| (so the paper's
sigma = 2 g), the paper linearises s2 at the splat mean: s2~ = max(0, s2 - 2 n g). The default
linearises the scaling distance s = sqrt(s2) instead: s~ = s - n g / s, s2~ = max(0, s~)^2 =
(s2 - n g)^2 / s2 when s2 > n g, else 0. Both are tangent planes of a convex function (s2 resp. s is
convex in the point), so both are lower bounds of the exact minimum over the splat's n-sigma
ellipsoid (never miss a splat whose ellipsoid reaches into the link); the distance's is the tighter
one, s~^2 = s2 - 2 n g + (n g / s)^2 >= s2 - 2 n g, and the gap is the quadratic term the paper
drops, which grows with s: a thin link (a Go2 calf, 2 cm) "touched" by a 25 cm wall splat a metre
away under the paper's rule is 12 scaling distances clear of it under the distance rule.

Invalid queries (non-finite centre, rotation or semi-axes, a zero quaternion, a semi-axis <= 0)
are never reported free: their outputs are min_s2 = softmin = cost = NaN, n_colliding = -1,
in_collision = True, and the smallest invalid query index is written to ``bad[0]``.

GROUP BOUND (per-configuration kernel). A robot's ellipsoids are grouped by the rigid body (link)
they belong to; ``robot_collide_kernel`` runs one thread per configuration. The distance to the
nearest mean, D, is 1-Lipschitz, so at a group's centroid c_g (a fixed point of the link: the mean
of its ellipsoid centres), D(c_e) >= D(c_g) - |c_e - c_g| for every member e. With
R_g >= max_e (|c_e - c_g| + rho_top(e)) (rho_top(e): e's search radius for the scene's largest std at
cap 1; |c_e - c_g| measured in the link frame; padded against float32 rounding), a mean-distance
bound d_lb(c_g) > R_g gives D(c_e) > rho_top(e) for every member: each of them would skip every tier
in :func:`link_collides` and read free, so the group is free with one read instead of one per
member. Member e gets the FREE SLACK d_lb(c_g) - |c_e - c_g| - rho_top(e) >= d_lb(c_g) - R_g (an
ellipsoid whose centre moves less than that, in any orientation, still has D > rho_top). Other groups test their members one by one, and
the first colliding member ends the configuration: the answer is "any ellipsoid collides", equal to
``collides_robot(...).any(-1)`` (the same per-ellipsoid test decides every member that is read).
"""

from __future__ import annotations

from .._warp import wp as _wp
from ..robots.wp_fk import FKModel, fk_config

wp = _wp()
wp.set_module_options({"enable_backward": False})  # forward only: halves the compile time

#: Relative slack of the search radius against float32 rounding.
RHO_SLACK = wp.constant(1.0001)
# Softmin terms exp(-t (v - pivot)) below exp(-20) ~ 2e-9 are skipped: the sum (>= 1) changes by
# less than N * 2e-9 relative, so the softmin moves by < N * 2e-9 / t (1e-7 for N = 500, t = 10).
SOFTMIN_SKIP = wp.constant(20.0)
#: bad[0] when every query was valid.
NO_BAD = 2147483647
#: Row clipping (ROW_CLIP in the module docstring) only for links with a_max / a_min up to this:
#: the float32 Schur complement loses about (a_max / a_min)^2 ulps, which the margins below cover.
ROW_CLIP_MAX_RATIO = wp.constant(50.0)
#: Margins of the clipped rows against float32 rounding: the ellipsoid's level is grown by 2% and the
#: tube's smallest level q shrunk by 2%, which is larger than 2 (a_max / a_min)^2 ulps for ratio <= 50.
ROW_S_GROW = wp.constant(1.02)
ROW_Q_SHRINK = wp.constant(0.98)
#: The mean-distance bound outside the grid (distance to the means' box) is shrunk by this against
#: float32 rounding (the per-voxel bounds carry their own margin, see :mod:`.wp_metric`).
DIST_SHRINK = wp.constant(0.999)
#: RIGID SLACK (``want_slack`` 2): a link near splats is scanned out to the scaling distance
#: s* (1 + min(target / a_min, RIGID_SLACK_MAX)): its rigid slack reaches at most RIGID_SLACK_MAX a_min.
RIGID_SLACK_MAX = wp.constant(1.0)
#: Rows holding at most this many splats are scanned whole (clipping costs more than it saves).
ROW_CLIP_MIN = wp.constant(8)
#: HIT BOUND: a link collides when a counted mean lies within this fraction of its smallest semi-axis
#: of its centre (the margin, 0.1%, is far above float32 rounding of the scaling distance).
HIT_SHRINK = wp.constant(0.999)


#: COVER SPHERES: the most spheres a near link's cover uses (along its longest axis).
COVER_MAX = wp.constant(4)
#: CELL BOXES: cells holding at most this many splats are read without testing their box.
CELL_BOX_MIN = wp.constant(16)
#: CELL BOXES: a cell is skipped when its bound times this exceeds the cut (0.1%, above the float32
#: rounding of the bound, whose box is also padded; see :func:`cell_s2_lb`).
CELL_BOX_SHRINK = wp.constant(0.999)


@wp.func
def search_radius(n_sigma: float, sigma_g: float, a_min: float, a_max: float, cap: float):
    """rho = a_max (k + sqrt(k^2 + cap)) (1 + 1e-4), k = n_sigma sigma_g / a_min: splats beyond have s2~ >= cap.

    The single definition of the bound: a ``@wp.func`` that Warp also evaluates in Python scope
    (float64 there), so the glue and the tests call this very function.
    """
    k = n_sigma * sigma_g / a_min
    return a_max * (k + wp.sqrt(k * k + cap)) * RHO_SLACK


@wp.func
def free_scale(n_sigma: float, sigma_g: float, a_min: float):
    """s* = k + sqrt(k^2 + 1), k = n_sigma sigma_g / a_min: a splat of std at most sigma_g whose mean
    lies at scaling distance s >= s* from the link has s2~ >= 1 (the radius bound above, cap 1)."""
    k = n_sigma * sigma_g / a_min
    return k + wp.sqrt(k * k + 1.0)


@wp.struct
class LinkBatch:
    """B query ellipsoids (world frame, scene units). Rotations and semi-axes are read with a period
    (row ``q % period``) so that a per-link (E, ...) array broadcasts over a (..., E) batch."""

    centers: wp.array(dtype=wp.vec3)  # (B,) link centres, world frame
    quats: wp.array(dtype=wp.vec4)  # (P_rot,) wxyz world <- link, used when rot_mode == 1 (normalised here)
    rots: wp.array(dtype=wp.mat33)  # (P_rot,) world <- link, used when rot_mode == 2
    axes: wp.array(dtype=wp.vec3)  # (P_axes,) semi-axes (a, b, c) along the link's x, y, z
    rot_mode: int  # 0 identity (no rotation given), 1 quaternions, 2 rotation matrices
    rot_period: int
    axes_period: int
    order: wp.array(dtype=wp.int32)  # (B,) launch position -> query index (spatially sorted), used when use_order == 1
    use_order: int


@wp.struct
class SplatTiers:
    """The scene in one grid set's memory order (see the module docstring)."""

    means: wp.array(dtype=wp.vec3)  # (N,) splat means, world frame
    mrows: wp.array(dtype=wp.mat33)  # (N,) diag(s) R^T per splat
    opacity: wp.array(dtype=wp.float32)  # (N,) opacity in [0, 1]
    cell_start: wp.array(dtype=wp.int32)  # tier j's cell k holds splats [cell_start[cell_base[j] + k], cell_start[cell_base[j] + k + 1])
    cell_base: wp.array(dtype=wp.int32)  # (T,) first entry of tier j in cell_start (its cells + 1 entries)
    dims: wp.array(dtype=wp.vec3i)  # (T,) grid size per axis; cell (x, y, z) = floor(p / width) mod dims
    inv_w: wp.array(dtype=wp.float32)  # (T,) 1 / cell width
    cell_lo: wp.array(dtype=wp.vec3i)  # (T,) smallest floor(p / width) of the tier's splats per axis (before the wrap)
    cell_hi: wp.array(dtype=wp.vec3i)  # (T,) largest
    offset: wp.array(dtype=wp.int32)  # (T + 1,) tier j = [offset[j], offset[j + 1])
    sigma: wp.array(dtype=wp.float32)  # (T,) largest std in the tier
    n_tiers: int
    box_base: wp.array(dtype=wp.int32)  # (T,) CELL BOXES: tier j's cell k has its box at box_base[j] + k; -1: the tier has none
    cell_box_lo: wp.array(dtype=wp.vec3)  # the smallest coordinates of the cell's means
    cell_box_hi: wp.array(dtype=wp.vec3)  # ... the largest


@wp.struct
class MeanDistanceGrid:
    """A lower bound on the distance from a point to the nearest splat mean (MEAN DISTANCE GRID in
    the module docstring); ``use == 0``: none (the bound is 0 everywhere)."""

    lb: wp.array(dtype=wp.float32)  # (nx * ny * nz,) per voxel: <= the distance from any point of the voxel to any mean
    origin: wp.vec3  # the grid's lower corner (world frame)
    inv_v: float  # 1 / voxel side
    dims: wp.vec3i  # voxels per axis (x fastest)
    box_lo: wp.vec3  # the bounding box of every mean (the bound outside the grid: distance to it)
    box_hi: wp.vec3
    use: int
    ub: wp.array(dtype=wp.float32)  # (nx * ny * nz,) per voxel: >= the distance from any point of the voxel to the nearest mean of opacity >= ub_opacity (HIT BOUND)
    ub_opacity: float  # the opacity threshold of the means ub counts (a splat below it may be free space)
    use_ub: int  # 0: no upper bounds (ub is a placeholder)


@wp.func
def voxel_index(g: MeanDistanceGrid, c: wp.vec3):
    """The flat index (x fastest) of the grid voxel holding ``c``, or -1 outside the grid (or NaN)."""
    fx = (c[0] - g.origin[0]) * g.inv_v
    fy = (c[1] - g.origin[1]) * g.inv_v
    fz = (c[2] - g.origin[2]) * g.inv_v
    if fx >= 0.0 and fy >= 0.0 and fz >= 0.0 and fx < float(g.dims[0]) and fy < float(g.dims[1]) and fz < float(g.dims[2]):
        ix = wp.min(int(fx), g.dims[0] - 1)
        iy = wp.min(int(fy), g.dims[1] - 1)
        iz = wp.min(int(fz), g.dims[2] - 1)
        return (iz * g.dims[1] + iy) * g.dims[0] + ix
    return -1


@wp.func
def mean_distance_lb(g: MeanDistanceGrid, c: wp.vec3):
    """A lower bound (>= 0) on the distance from ``c`` to every splat mean: the larger of the
    distance to the means' bounding box and the voxel's stored bound (0 when ``g.use == 0``)."""
    if g.use == 0:
        return float(0.0)
    dx = wp.max(wp.max(g.box_lo[0] - c[0], c[0] - g.box_hi[0]), 0.0)
    dy = wp.max(wp.max(g.box_lo[1] - c[1], c[1] - g.box_hi[1]), 0.0)
    dz = wp.max(wp.max(g.box_lo[2] - c[2], c[2] - g.box_hi[2]), 0.0)
    d = wp.sqrt(dx * dx + dy * dy + dz * dz) * DIST_SHRINK
    v = voxel_index(g, c)
    if v >= 0:
        d = wp.max(d, g.lb[v])
    return d


@wp.kernel
def mean_distance_lb_kernel(g: MeanDistanceGrid, pts: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.float32)):
    """out[i] = :func:`mean_distance_lb` at pts[i] (tests, diagnostics)."""
    i = wp.tid()
    out[i] = mean_distance_lb(g, pts[i])


@wp.struct
class MetricParams:
    """:class:`~splatplan.metric.config.MetricConfig` as the kernels see it."""

    n_sigma: float
    cap: float  # s2_cap: exactness threshold and neighbourhood N(q) = {s2~ < cap}; 1 for collides
    softmin_t: float
    softmin_mean: int  # 1: log-mean-exp (adds log|N| / t), 0: log-sum-exp
    d_max: float
    gamma: float
    s_min: float
    reduce_code: int  # 0 mean, 1 sum, 2 max
    pow_m: int  # > 0 when softmin_t == pow_m * gamma (softmin terms from the cost's exp), else 0
    k_collide: int  # in collision when more than k splats have s2~ < 1
    opacity_min: float  # splats with opacity below it are free space
    opacity_scaled: int  # 1: inflation n_sigma * o_i * sigma_i
    use_opacity: int  # 1 when either opacity option is active (else opacity is never read)
    collide_clip: int  # 1: the collision-only kernel clips rows to the link's ellipsoid too (ROW_CLIP)
    collide_cover: int  # 1: the collision-only kernel tests near links by their COVER SPHERES first
    lin_distance: int  # 1: linearise the scaling distance s, 0: s2 (the paper) (LINEARISATION)


@wp.func
def hit_bound(g: MeanDistanceGrid, p: MetricParams, c: wp.vec3, a_min: float):
    """True when a mean that counts lies within HIT_SHRINK a_min of ``c`` by the voxel's upper bound
    (HIT BOUND in the module docstring): the link of smallest semi-axis ``a_min`` centred at ``c``
    collides. False where the bound does not apply (no grid, k_collide > 0, a looser opacity rule)."""
    if g.use_ub == 0 or p.k_collide != 0:
        return False
    if p.use_opacity != 0 and p.opacity_min > g.ub_opacity:
        return False
    v = voxel_index(g, c)
    if v < 0:
        return False
    return g.ub[v] < a_min * HIT_SHRINK


@wp.kernel
def hit_bound_kernel(g: MeanDistanceGrid, p: MetricParams, pts: wp.array(dtype=wp.vec3), a_min: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.bool)):
    """out[i] = :func:`hit_bound` at pts[i] for a link of smallest semi-axis a_min[i] (tests)."""
    i = wp.tid()
    out[i] = hit_bound(g, p, pts[i], a_min[i])


@wp.struct
class MetricOutputs:
    min_s2: wp.array(dtype=wp.float32)  # (B,)
    n_colliding: wp.array(dtype=wp.int32)  # (B,)
    in_collision: wp.array(dtype=wp.bool)  # (B,)
    softmin: wp.array(dtype=wp.float32)  # (B,)
    cost: wp.array(dtype=wp.float32)  # (B,)
    bad: wp.array(dtype=wp.int32)  # (1,) smallest invalid query index, NO_BAD if none


@wp.struct
class LanePartials:
    """Several threads ("lanes") per query in the full kernel (LANES in the module docstring):
    lane l of query q takes every ``lanes``-th splat of each visited cell run and writes its
    partial sums at row q * lanes + l; :func:`metric_lanes_combine_kernel` reduces them in lane
    order. ``lanes == 1``: the kernel writes the outputs itself (these arrays are not read)."""

    lanes: int
    best: wp.array(dtype=wp.float32)  # (B * lanes,) min s2~
    ncol: wp.array(dtype=wp.int32)  # splats with s2~ < 1
    n_nb: wp.array(dtype=wp.int32)  # |N(q)| seen by the lane; -1: invalid query (lane 0 wrote the outputs)
    pivot: wp.array(dtype=wp.float32)  # softmin pivot of the lane
    acc: wp.array(dtype=wp.float32)  # sum exp(-t (s2~ - pivot)) of the lane
    c_sum: wp.array(dtype=wp.float32)
    c_max: wp.array(dtype=wp.float32)


@wp.func
def quat_wxyz_to_mat(q: wp.vec4):
    """Rotation matrix of a wxyz quaternion (normalised here)."""
    return wp.quat_to_matrix(wp.normalize(wp.quat(q[1], q[2], q[3], q[0])))


@wp.func
def link_matrix(rot: wp.mat33, axes: wp.vec3):
    """A = R diag(1/a^2, 1/b^2, 1/c^2) R^T."""
    w = wp.vec3(1.0 / (axes[0] * axes[0]), 1.0 / (axes[1] * axes[1]), 1.0 / (axes[2] * axes[2]))
    return rot * wp.diag(w) * wp.transpose(rot)


@wp.func
def link_rotation(links: LinkBatch, q: int):
    """World <- link rotation of query q (identity when none was given)."""
    if links.rot_mode == 1:
        return quat_wxyz_to_mat(links.quats[q % links.rot_period])
    if links.rot_mode == 2:
        return links.rots[q % links.rot_period]
    return wp.identity(n=3, dtype=float)


@wp.func
def link_valid(links: LinkBatch, q: int, c: wp.vec3, ax: wp.vec3):
    ok = wp.isfinite(c) and wp.isfinite(ax) and wp.min(ax) > 0.0
    if links.rot_mode == 1:
        qv = links.quats[q % links.rot_period]
        ok = ok and wp.isfinite(qv) and wp.length(qv) > 1.0e-8
    if links.rot_mode == 2:
        ok = ok and wp.isfinite(links.rots[q % links.rot_period])
    return ok


@wp.func
def inflated_s2(s2: float, g: float, n_sigma: float, lin_distance: int):
    """s2~ from s2 and g = |diag(s) R^T A d| (LINEARISATION): the paper's max(0, s2 - 2 n g), or with
    ``lin_distance`` the squared linearised distance (s2 - n g)^2 / s2 (0 when s2 <= n g)."""
    if lin_distance == 0:
        return wp.max(0.0, s2 - n_sigma * 2.0 * g)
    t = s2 - n_sigma * g
    if t <= 0.0:
        return 0.0
    return t * t / s2


@wp.func
def link_s2(d: wp.vec3, dd: float, link_a: wp.mat33, sphere: bool, inv_r2: float, mrows: wp.array(dtype=wp.mat33), i: int, n_sigma: float, s2_cut: float,
            lin_distance: int):
    """s2~ of splat i (``mrows[i]`` = its diag(s) R^T, read only when n_sigma > 0); for a sphere link
    (A = I / r^2, so A d = d / r^2) it reuses dd = |d|^2. ``lin_distance``: LINEARISATION.

    For other links, a splat with s2 > s2_cut = (rho / a_max)^2 is returned as +inf before its
    inflation is computed: by the radius bound it has s2~ >= cap anyway (this prunes the corners
    of the bounding sphere of an elongated link cheaply).
    """
    if sphere:
        if n_sigma == 0.0:  # no inflation (the term below would be 0): skip the splat's matrix
            return dd * inv_r2
        return inflated_s2(dd * inv_r2, wp.length(mrows[i] * d) * inv_r2, n_sigma, lin_distance)
    ad = link_a * d
    s2 = wp.dot(d, ad)
    if s2 > s2_cut:
        return float(wp.inf)
    if n_sigma == 0.0:
        return wp.max(0.0, s2)
    return inflated_s2(s2, wp.length(mrows[i] * ad), n_sigma, lin_distance)


@wp.func
def cell_range(v: float, r: float, inv_w: float, dim: int, c_lo: int, c_hi: int):
    """(first cell, number of cells <= dim; 0 = none, complete) along one axis covering [v - r, v + r]
    (Warp's hash-grid rule) within the cells [c_lo, c_hi] that hold the tier's splats: no wrapped-around
    cell beyond the tier's extent is read. ``complete``: the range needs at most ``dim`` cells, so it
    does not wrap onto itself and every visited cell stands for one unwrapped cell index."""
    lo = int(wp.clamp(wp.floor((v - r) * inv_w), -1.0e9, 1.0e9))
    hi = int(wp.clamp(wp.floor((v + r) * inv_w), -1.0e9, 1.0e9))
    lo = wp.max(lo, c_lo)
    hi = wp.min(hi, c_hi)
    return lo, wp.max(wp.min(hi - lo + 1, dim), 0), hi - lo + 1 <= dim


@wp.func
def cell_pad(v: float):
    """Margin (in cells) around cell coordinate v against float32 rounding of the cell rule
    floor(p * inv_w): 1% of a cell plus a relative ulp margin."""
    return 0.01 + 1.0e-6 * wp.abs(v)


@wp.func
def row_bounds(yy: int, zz: int, inv_w: float):
    """World y and z intervals of the unwrapped cell row (yy, zz), padded by :func:`cell_pad`."""
    py = cell_pad(float(yy))
    pz = cell_pad(float(zz))
    w = 1.0 / inv_w
    return (float(yy) - py) * w, (float(yy) + 1.0 + py) * w, (float(zz) - pz) * w, (float(zz) + 1.0 + pz) * w


@wp.func
def schur_form(a: wp.mat33):
    """(1 / a_xx, a_xy, a_xz) and the yz Schur complement (c_yy, c_yz, c_zz) of the link matrix, for :func:`row_x_span`."""
    inv_axx = 1.0 / a[0, 0]
    bxy = a[0, 1]
    bxz = a[0, 2]
    e1 = wp.vec3(inv_axx, bxy, bxz)
    e2 = wp.vec3(a[1, 1] - bxy * bxy * inv_axx, a[1, 2] - bxy * bxz * inv_axx, a[2, 2] - bxz * bxz * inv_axx)
    return e1, e2


@wp.func
def run_count(cell_start: wp.array(dtype=wp.int32), row: int, x0: int, n: int, dim: int):
    """Number of splats in the n cells of a row from wrapped cell x0 on (wrapping like the scan)."""
    x1 = x0 + n - 1
    if x1 < dim:
        return cell_start[row + x1 + 1] - cell_start[row + x0]
    return cell_start[row + dim] - cell_start[row + x0] + cell_start[row + x1 - dim + 1] - cell_start[row]


@wp.func
def x_cell(x: float, inv_w: float, side: float):
    """Unwrapped x cell of a span end, moved outwards (side -1: low end, +1: high end) by :func:`cell_pad`."""
    v = x * inv_w
    return int(wp.clamp(wp.floor(v + side * cell_pad(v)), -1.0e9, 1.0e9))


@wp.func
def row_x_span(c: wp.vec3, e1: wp.vec3, e2: wp.vec3, s_cut: float, cb: wp.vec3, rb: float, y0: float, y1: float, z0: float, z1: float, ball_only: bool):
    """(x_lo, x_hi) world x interval holding every point p of the tube y in [y0, y1], z in [z0, z1]
    with (p - c)^T a (p - c) <= s_cut (the link's s2 <= s2_cut ellipsoid) and |p - cb| <= rb (the
    query ball); x_lo > x_hi when the tube misses either (see ROW_CLIP in the module docstring)."""
    # ball: the tube's nearest point to cb in y and z
    ey = wp.max(wp.max(y0 - cb[1], cb[1] - y1), 0.0)
    ez = wp.max(wp.max(z0 - cb[2], cb[2] - z1), 0.0)
    r2 = rb * rb - ey * ey - ez * ez
    if r2 < 0.0:
        return 1.0, 0.0
    hb = wp.sqrt(r2)
    if ball_only:  # a sphere link: its s2 <= s2_cut ellipsoid is the ball itself
        return cb[0] - hb, cb[0] + hb
    # ellipsoid: x = c_x + m(dy, dz) +- sqrt((s - q(dy, dz)) / a_xx), m linear, q the Schur complement form
    inv_axx = e1[0]
    bxy = e1[1]
    bxz = e1[2]
    cyy = e2[0]
    cyz = e2[1]
    czz = e2[2]
    dy0 = y0 - c[1]
    dy1 = y1 - c[1]
    dz0 = z0 - c[2]
    dz1 = z1 - c[2]
    qmin = float(0.0)
    if not (dy0 <= 0.0 and dy1 >= 0.0 and dz0 <= 0.0 and dz1 >= 0.0):
        # the convex q has its minimum (0 at the centre) outside the rectangle: on an edge
        qmin = float(wp.inf)
        for e in range(2):
            dy = dy0
            if e == 1:
                dy = dy1
            dz = wp.clamp(-cyz * dy / czz, dz0, dz1)
            qmin = wp.min(qmin, cyy * dy * dy + 2.0 * cyz * dy * dz + czz * dz * dz)
            dz = dz0
            if e == 1:
                dz = dz1
            dy = wp.clamp(-cyz * dz / cyy, dy0, dy1)
            qmin = wp.min(qmin, cyy * dy * dy + 2.0 * cyz * dy * dz + czz * dz * dz)
        qmin = wp.max(qmin * ROW_Q_SHRINK, 0.0)
    s = s_cut * ROW_S_GROW
    if qmin > s:
        return 1.0, 0.0
    h = wp.sqrt((s - qmin) * inv_axx)
    m_lo = -(wp.max(bxy * dy0, bxy * dy1) + wp.max(bxz * dz0, bxz * dz1)) * inv_axx
    m_hi = -(wp.min(bxy * dy0, bxy * dy1) + wp.min(bxz * dz0, bxz * dz1)) * inv_axx
    x_lo = wp.max(c[0] + m_lo - h, cb[0] - hb)
    x_hi = wp.min(c[0] + m_hi + h, cb[0] + hb)
    return x_lo, x_hi


@wp.func
def clipped_row(c: wp.vec3, e1: wp.vec3, e2: wp.vec3, s_cut: float, rb: float, yy: int, zz: int, inv_w: float, xs: int, xa: int, xb: int, ball_only: bool):
    """ROW_CLIP: cells xs + xa .. xs + xb of the unwrapped row (yy, zz) narrowed to the x span that
    can hold a splat of the link's s2 <= s_cut ellipsoid within the query ball (centre c, radius
    rb); returns (xa, xb), with xb < xa when no cell of the row can."""
    y0, y1, z0, z1 = row_bounds(yy, zz, inv_w)
    xl, xh = row_x_span(c, e1, e2, s_cut, c, rb, y0, y1, z0, z1, ball_only)
    if xl > xh:
        return xa, xa - 1
    return wp.max(xa, x_cell(xl, inv_w, -1.0) - xs), wp.min(xb, x_cell(xh, inv_w, 1.0) - xs)


@wp.func
def row_runs(x0s: int, xa: int, xb: int, dim: int):
    """Cells xs + xa .. xs + xb of a row whose first cell wraps to x0s: (x0 < dim, x1 = x0 + xb - xa,
    the number of contiguous runs: 2 when x1 >= dim wraps past dim - 1, else 1); see :func:`run_cells`."""
    x0 = x0s + xa
    if x0 >= dim:
        x0 -= dim
    x1 = x0 + xb - xa
    n_run = int(1)
    if x1 >= dim:
        n_run = 2
    return x0, x1, n_run


@wp.func
def run_cells(run: int, x0: int, x1: int, dim: int):
    """Wrapped cells (a0, a1) of the contiguous run ``run`` of a row's unwrapped-order cells x0 .. x1
    (x0 < dim): run 0 is x0 .. min(x1, dim - 1), run 1 (when x1 >= dim) wraps to 0 .. x1 - dim."""
    if run == 1:
        return 0, x1 - dim
    return x0, wp.min(x1, dim - 1)


@wp.func
def wrap(x: int, dim: int):
    """x mod dim in [0, dim)."""
    m = x % dim
    if m < 0:
        m += dim
    return m


@wp.func
def link_box(ax: wp.vec3, n_sigma_g: float, cap: float):
    """Half extents (link frame) of a box holding every splat with s2~ < cap, for splats of std <= sigma_g
    (n_sigma_g = n_sigma sigma_g): |e_k| < n_sigma_g + a_k sqrt(cap + sum_j (n_sigma_g / a_j)^2) (see the
    module docstring), plus float slack."""
    k2 = n_sigma_g * n_sigma_g * (1.0 / (ax[0] * ax[0]) + 1.0 / (ax[1] * ax[1]) + 1.0 / (ax[2] * ax[2]))
    root = wp.sqrt(cap + k2)
    return wp.vec3(n_sigma_g + ax[0] * root, n_sigma_g + ax[1] * root, n_sigma_g + ax[2] * root) * RHO_SLACK


@wp.func
def box_reach(rot: wp.mat33, h: wp.vec3, i: int):
    """Half extent along world axis i of the link-frame box of half extents h (rotation rot: world <- link)."""
    return wp.abs(rot[i, 0]) * h[0] + wp.abs(rot[i, 1]) * h[1] + wp.abs(rot[i, 2]) * h[2]


@wp.func
def splat_inflation(splats: SplatTiers, p: MetricParams, i: int):
    """n_sigma for splat i under the opacity options; -1 when the splat counts as free space."""
    if p.use_opacity == 0:
        return p.n_sigma
    o = splats.opacity[i]
    if o < p.opacity_min:
        return -1.0
    if p.opacity_scaled != 0:
        return p.n_sigma * o
    return p.n_sigma


@wp.func
def write_outputs(out: MetricOutputs, q: int, p: MetricParams, best: float, ncol: int, n_nb: int, pivot: float, acc: float, c_sum: float, c_max: float):
    """The five outputs of query q from its accumulated sums (one thread, or the lanes combined)."""
    t = p.softmin_t
    out.min_s2[q] = best
    out.n_colliding[q] = ncol
    out.in_collision[q] = ncol > p.k_collide
    if n_nb > 0:
        soft = pivot - wp.log(acc) / t
        if p.softmin_mean != 0:
            soft += wp.log(float(n_nb)) / t
        out.softmin[q] = soft
        if p.reduce_code == 0:
            out.cost[q] = c_sum / float(n_nb)
        elif p.reduce_code == 1:
            out.cost[q] = c_sum
        else:
            out.cost[q] = c_max
    else:
        out.softmin[q] = float(wp.inf)
        out.cost[q] = 0.0


@wp.kernel
def metric_full_kernel(
    offset: int,  # first query handled by this launch (CPU launches split the batch)
    links: LinkBatch,
    splats: SplatTiers,
    p: MetricParams,
    out: MetricOutputs,
    lp: LanePartials,
):
    tid = wp.tid() + offset  # one thread per (query, lane): lanes of a query are adjacent threads
    lane = tid % lp.lanes
    q = tid // lp.lanes
    if links.use_order != 0:
        q = links.order[q]  # neighbouring threads take neighbouring queries: coherent splat reads
    c = links.centers[q]
    ax = links.axes[q % links.axes_period]
    if not link_valid(links, q, c, ax):
        if lane == 0:
            out.min_s2[q] = wp.nan
            out.n_colliding[q] = -1
            out.in_collision[q] = True
            out.softmin[q] = wp.nan
            out.cost[q] = wp.nan
            wp.atomic_min(out.bad, 0, q)
        if lp.lanes > 1:
            lp.n_nb[q * lp.lanes + lane] = -1
        return
    rot = link_rotation(links, q)
    a = link_matrix(rot, ax)
    a_min = wp.min(ax)
    a_max = wp.max(ax)
    clip_ok = a_max <= ROW_CLIP_MAX_RATIO * a_min  # rows clipped to the link's ellipsoid (ROW_CLIP)
    e1, e2 = schur_form(a)

    best = float(wp.inf)  # min s2~ over visited splats
    ncol = int(0)  # splats with s2~ < 1
    pivot = float(wp.inf)  # running minimum of s2~ over N(q) (softmin pivot)
    acc = float(0.0)  # sum exp(-t (s2~ - pivot)) over N(q)
    n_nb = int(0)  # |N(q)|
    c_sum = float(0.0)
    c_max = float(0.0)
    pg = float(1.0)  # exp(gamma (pivot - s_min)), updated with the pivot
    sphere = a_min == a_max  # A = I / r^2: cheaper s2~
    inv_r2 = 1.0 / (a_min * a_min)
    cap = p.cap
    gamma = p.gamma
    t = p.softmin_t

    for j in range(splats.n_tiers):
        rho = search_radius(p.n_sigma, splats.sigma[j], a_min, a_max, cap)
        rho2 = rho * rho
        s2_cut = rho2 / (a_max * a_max)
        # every splat with s2~ < cap lies in the ball of radius rho and in the link-frame box h
        h = link_box(ax, p.n_sigma * splats.sigma[j], cap)
        r_x = wp.min(rho, box_reach(rot, h, 0))
        r_y = wp.min(rho, box_reach(rot, h, 1))
        r_z = wp.min(rho, box_reach(rot, h, 2))
        inv_w = splats.inv_w[j]
        dim = splats.dims[j]
        cb = splats.cell_base[j]
        c_lo = splats.cell_lo[j]
        c_hi = splats.cell_hi[j]
        xs, nx, fx = cell_range(c[0], r_x, inv_w, dim[0], c_lo[0], c_hi[0])
        ys, ny, fy = cell_range(c[1], r_y, inv_w, dim[1], c_lo[1], c_hi[1])
        zs, nz, fz = cell_range(c[2], r_z, inv_w, dim[2], c_lo[2], c_hi[2])
        clip = clip_ok and fx and fy and fz
        x0s = wrap(xs, dim[0])
        for iz in range(nz):
            z = wrap(zs + iz, dim[2])
            for iy in range(ny):
                row = cb + (z * dim[1] + wrap(ys + iy, dim[1])) * dim[0]
                n_in = run_count(splats.cell_start, row, x0s, nx, dim[0])
                if n_in == 0:
                    continue  # an empty row (most rows around a link in free space)
                xa = int(0)  # cells xs + xa .. xs + xb of this row (unwrapped)
                xb = nx - 1
                if clip and n_in > ROW_CLIP_MIN:
                    xa, xb = clipped_row(c, e1, e2, s2_cut, rho, ys + iy, zs + iz, inv_w, xs, xa, xb, sphere)
                    if xb < xa:
                        continue
                x0, x1, n_run = row_runs(x0s, xa, xb, dim[0])  # cells x0..x1 of a row, wrapping past dim[0] - 1 into a second run
                for run in range(n_run):
                    a0, a1 = run_cells(run, x0, x1, dim[0])
                    for i in range(splats.cell_start[row + a0] + lane, splats.cell_start[row + a1 + 1], lp.lanes):
                        d = splats.means[i] - c
                        dd = wp.dot(d, d)
                        if dd <= rho2:
                            ns = splat_inflation(splats, p, i)
                            if ns < 0.0:
                                continue
                            v = link_s2(d, dd, a, sphere, inv_r2, splats.mrows, i, ns, s2_cut, p.lin_distance)
                            best = wp.min(best, v)
                            if v < 1.0:
                                ncol += 1
                            if v < cap:
                                n_nb += 1
                                eg = wp.exp(-gamma * (v - p.s_min))  # the one exp per neighbour in the common case
                                cv = p.d_max * wp.min(eg, 1.0)  # d_max exp(-gamma max(v - s_min, 0))
                                if v < pivot:
                                    acc = acc * wp.exp(-t * (pivot - v)) + 1.0
                                    pivot = v
                                    pg = wp.exp(gamma * (pivot - p.s_min))  # eg * pg = exp(-gamma (v - pivot))
                                elif p.pow_m > 0:
                                    # t = m gamma: exp(-t (v - pivot)) = (eg * pg)^m, no second exp
                                    e = eg * pg
                                    term = e
                                    for _k in range(p.pow_m - 1):
                                        term = term * e
                                    acc += term
                                elif t * (v - pivot) < SOFTMIN_SKIP:
                                    acc += wp.exp(-t * (v - pivot))
                                c_sum += cv
                                c_max = wp.max(c_max, cv)

    if lp.lanes == 1:
        write_outputs(out, q, p, best, ncol, n_nb, pivot, acc, c_sum, c_max)
    else:
        k = q * lp.lanes + lane
        lp.best[k] = best
        lp.ncol[k] = ncol
        lp.n_nb[k] = n_nb
        lp.pivot[k] = pivot
        lp.acc[k] = acc
        lp.c_sum[k] = c_sum
        lp.c_max[k] = c_max


@wp.kernel
def metric_lanes_combine_kernel(lp: LanePartials, p: MetricParams, out: MetricOutputs):
    """Reduce the lanes' partial sums of each query in lane order (deterministic) and write its outputs."""
    q = wp.tid()
    base = q * lp.lanes
    if lp.n_nb[base] < 0:
        return  # invalid query: written by its lane 0
    best = float(wp.inf)
    ncol = int(0)
    n_nb = int(0)
    pivot = float(wp.inf)
    c_sum = float(0.0)
    c_max = float(0.0)
    for l in range(lp.lanes):
        k = base + l
        best = wp.min(best, lp.best[k])
        ncol += lp.ncol[k]
        c_sum += lp.c_sum[k]
        c_max = wp.max(c_max, lp.c_max[k])
        if lp.n_nb[k] > 0:
            n_nb += lp.n_nb[k]
            pivot = wp.min(pivot, lp.pivot[k])
    acc = float(0.0)
    for l in range(lp.lanes):
        k = base + l
        if lp.n_nb[k] > 0:
            acc += lp.acc[k] * wp.exp(-p.softmin_t * (lp.pivot[k] - pivot))
    write_outputs(out, q, p, best, ncol, n_nb, pivot, acc, c_sum, c_max)


@wp.func
def plain_s2(d: wp.vec3, dd: float, link_a: wp.mat33, sphere: bool, inv_r2: float):
    """s2 = d^T A d, the squared scaling distance of a splat mean at offset d (no inflation)."""
    if sphere:
        return dd * inv_r2
    return wp.dot(d, link_a * d)


@wp.func
def cover_margin(dgrid: MeanDistanceGrid, c: wp.vec3, rot: wp.mat33, ax: wp.vec3, s_star: float):
    """COVER SPHERES (module docstring): the smallest (mean-distance bound at a sphere's centre minus its
    radius) over K spheres along the longest axis that together cover the link scaled by ``s_star``;
    > 0: no mean lies in that scaled link (the test stops at the first sphere with <= 0); -1 for a
    link too close to a sphere for the cover to be tighter than its bounding sphere."""
    m = int(0)  # the longest axis
    if ax[1] > ax[m]:
        m = 1
    if ax[2] > ax[m]:
        m = 2
    a1 = ax[m]
    a2 = float(0.0)  # the second longest
    for k in range(3):
        if k != m:
            a2 = wp.max(a2, ax[k])
    n = wp.min(COVER_MAX, int(wp.ceil(2.0 * a1 / a2)))
    h = a1 / float(n)
    if h * h + a2 * a2 >= a1 * a1:
        return float(-1.0)  # (a near sphere: its middle spheres would reach farther than the link's bounding sphere)
    u = wp.vec3(rot[0, m], rot[1, m], rot[2, m])  # world direction of the longest axis
    e = a2 * a2 / (a1 * a1)
    best = float(1.0e30)
    for i in range(n):
        t = -a1 + h * float(2 * i + 1)  # the slab |x - t| <= h along the axis, its sphere centred at t
        lo = wp.max(t - h, -a1)
        hi = wp.min(t + h, a1)
        # a point of the slab at axis coordinate x lies within (x - t)^2 + a2^2 (1 - x^2 / a1^2) of the
        # centre (squared; convex in x, so largest at an end of the slab)
        r2 = wp.max((lo - t) * (lo - t) + a2 * a2 - e * lo * lo, (hi - t) * (hi - t) + a2 * a2 - e * hi * hi)
        x = c + u * (t * s_star)
        d = mean_distance_lb(dgrid, x) - wp.sqrt(wp.max(r2, 0.0)) * s_star * RHO_SLACK - 1.0e-5 * wp.length(x)
        best = wp.min(best, d)
        if best <= 0.0:
            break
    return best


@wp.func
def cell_s2_lb(c: wp.vec3, rot: wp.mat33, ax: wp.vec3, lo: wp.vec3, hi: wp.vec3):
    """CELL BOXES (module docstring): a lower bound on the squared scaling distance s2 = sum_k
    (u_k . (x - c))^2 / a_k^2 (u_k the link's axes, columns of ``rot``) over every point x of the box
    [lo, hi]: per axis, the distance from 0 of the box's projection interval, squared over a_k^2. The
    box is grown by 1e-5 (1 + |c|) against float32 rounding."""
    pad = 1.0e-5 * (1.0 + wp.length(c))
    ctr = (lo + hi) * 0.5 - c
    half = (hi - lo) * 0.5 + wp.vec3(pad, pad, pad)
    s2 = float(0.0)
    for k in range(3):
        u = wp.vec3(rot[0, k], rot[1, k], rot[2, k])
        p = wp.dot(u, ctr)
        r = wp.abs(u[0]) * half[0] + wp.abs(u[1]) * half[1] + wp.abs(u[2]) * half[2]
        m = wp.max(wp.abs(p) - r, 0.0)
        s2 += m * m / (ax[k] * ax[k])
    return s2


@wp.kernel
def cell_s2_lb_kernel(centers: wp.array(dtype=wp.vec3), rots: wp.array(dtype=wp.mat33), axes: wp.array(dtype=wp.vec3), lo: wp.array(dtype=wp.vec3),
                      hi: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.float32)):  # fmt: skip
    """out[i] = :func:`cell_s2_lb` of link i and box i (tests)."""
    i = wp.tid()
    out[i] = cell_s2_lb(centers[i], rots[i], axes[i], lo[i], hi[i])


@wp.kernel
def cover_margin_kernel(dgrid: MeanDistanceGrid, centers: wp.array(dtype=wp.vec3), rots: wp.array(dtype=wp.mat33), axes: wp.array(dtype=wp.vec3),
                        s_star: float, out: wp.array(dtype=wp.float32)):  # fmt: skip
    """out[i] = :func:`cover_margin` of link i (tests, diagnostics)."""
    i = wp.tid()
    out[i] = cover_margin(dgrid, centers[i], rots[i], axes[i], s_star)


@wp.func
def link_collides(links: LinkBatch, q: int, splats: SplatTiers, dgrid: MeanDistanceGrid, p: MetricParams, slack_mode: int, target: float):
    """The collision-only test of query ellipsoid q: (in collision, FREE SLACK, valid).

    Radius for cap = 1, stops at the (k+1)-th colliding splat; a tier whose search radius is below
    the mean-distance bound at the centre is skipped (no splat of it is within the radius: the
    outputs are unchanged). ``slack_mode`` 2 (RIGID SLACK): a link whose mean-distance slack is
    below ``target`` is scanned out to the scaling distance s* (1 + min(target / a_min,
    RIGID_SLACK_MAX)) and gets the rigid slack of its closest mean. An invalid query reads
    (True, 0, False)."""
    c = links.centers[q]
    ax = links.axes[q % links.axes_period]
    if not link_valid(links, q, c, ax):
        return True, float(0.0), False
    a_min = wp.min(ax)
    a_max = wp.max(ax)
    if hit_bound(dgrid, p, c, a_min):
        return True, float(0.0), True  # a counted mean inside the link (HIT BOUND): no splat is read
    d_lb = mean_distance_lb(dgrid, c)
    far_slack = float(0.0)
    s_top = float(0.0)  # the largest std of any tier
    for j in range(splats.n_tiers):
        s_top = wp.max(s_top, splats.sigma[j])
    if dgrid.use != 0:
        rho_top = search_radius(p.n_sigma, s_top, a_min, a_max, 1.0)
        if d_lb > rho_top:
            far_slack = (d_lb - rho_top) * DIST_SHRINK
            if slack_mode != 2 or far_slack >= target:
                return False, far_slack, True  # beyond every tier's radius: no splat is read
    rot = link_rotation(links, q)
    cover_slack = float(0.0)  # RIGID SLACK proven by the cover spheres
    if dgrid.use != 0 and p.collide_cover != 0 and a_max > a_min:  # COVER SPHERES
        s_top_star = free_scale(p.n_sigma, s_top, a_min)
        cover = cover_margin(dgrid, c, rot, ax, s_top_star)
        if cover > 0.0:  # no mean in s* E: free, no splat is read
            if slack_mode != 2 or target <= 0.0:
                return False, far_slack, True
            cover_slack = cover / s_top_star * DIST_SHRINK
            if wp.max(far_slack, cover_slack) >= target:
                return False, wp.max(far_slack, cover_slack), True
    # RIGID SLACK: tier j is scanned out to s*_j (1 + lam) (every mean with s below it is read)
    scan = slack_mode == 2 and target > 0.0
    lam = float(0.0)
    if scan:
        lam = wp.min(target / a_min, RIGID_SLACK_MAX)
    near_slack = lam * a_min  # (what a tier with no mean that close leaves)
    a = link_matrix(rot, ax)
    ncol = int(0)
    sphere = a_min == a_max
    inv_r2 = 1.0 / (a_min * a_min)
    k_collide = p.k_collide
    clip_ok = a_max <= ROW_CLIP_MAX_RATIO * a_min
    e1, e2 = schur_form(a)
    for j in range(splats.n_tiers):
        if ncol > k_collide:
            break
        s_star = free_scale(p.n_sigma, splats.sigma[j], a_min)  # s >= s*_j: s2~ >= 1 for this tier's splats
        cap = float(1.0)
        if scan:
            cap = s_star * s_star * (1.0 + lam) * (1.0 + lam)
        min_s2 = cap
        rho = search_radius(p.n_sigma, splats.sigma[j], a_min, a_max, cap)
        if d_lb > rho:
            continue  # every mean is farther than the radius (MEAN DISTANCE GRID)
        rho2 = rho * rho
        s2_cut = rho2 / (a_max * a_max)
        s2_cut1 = s2_cut  # the collision test's cut (cap 1)
        if scan:
            rho_1 = search_radius(p.n_sigma, splats.sigma[j], a_min, a_max, 1.0)
            s2_cut1 = rho_1 * rho_1 / (a_max * a_max)
        inv_w = splats.inv_w[j]
        dim = splats.dims[j]
        cb = splats.cell_base[j]
        bb = splats.box_base[j]  # CELL BOXES of this tier (-1: none)
        c_lo = splats.cell_lo[j]
        c_hi = splats.cell_hi[j]
        r_x = rho
        r_y = rho
        r_z = rho
        if not sphere:  # the ball and the link box (module docstring); a sphere's box is never smaller
            h = link_box(ax, p.n_sigma * splats.sigma[j], cap)
            r_x = wp.min(rho, box_reach(rot, h, 0))
            r_y = wp.min(rho, box_reach(rot, h, 1))
            r_z = wp.min(rho, box_reach(rot, h, 2))
        xs, nx, fx = cell_range(c[0], r_x, inv_w, dim[0], c_lo[0], c_hi[0])
        ys, ny, fy = cell_range(c[1], r_y, inv_w, dim[1], c_lo[1], c_hi[1])
        zs, nz, fz = cell_range(c[2], r_z, inv_w, dim[2], c_lo[2], c_hi[2])
        clip = p.collide_clip != 0 and clip_ok and fx and fy and fz  # ROW_CLIP (TierConfig.collide_row_clip)
        x0s = wrap(xs, dim[0])
        for iz in range(nz):
            if ncol > k_collide:
                break
            z = wrap(zs + iz, dim[2])
            for iy in range(ny):
                if ncol > k_collide:
                    break
                row = cb + (z * dim[1] + wrap(ys + iy, dim[1])) * dim[0]
                xa = int(0)  # cells xs + xa .. xs + xb of this row (unwrapped)
                xb = nx - 1
                if clip:
                    if run_count(splats.cell_start, row, x0s, nx, dim[0]) <= ROW_CLIP_MIN:
                        xa = 0  # (a short row is scanned whole)
                    else:
                        xa, xb = clipped_row(c, e1, e2, s2_cut, rho, ys + iy, zs + iz, inv_w, xs, xa, xb, sphere)
                        if xb < xa:
                            continue
                x0, x1, n_run = row_runs(x0s, xa, xb, dim[0])
                for run in range(n_run):
                    a0, a1 = run_cells(run, x0, x1, dim[0])
                    i_end = splats.cell_start[row + a1 + 1]
                    i = splats.cell_start[row + a0]
                    cell = a0  # CELL BOXES: the run cell by cell (else as one range), a cell beyond the cut skipped
                    while i < i_end:
                        if ncol > k_collide:
                            break
                        i_stop = i_end
                        if bb >= 0:
                            i_stop = splats.cell_start[row + cell + 1]  # (cell holds [i, i_stop): the cells before it are done)
                            k_box = bb + row - cb + cell
                            cell += 1
                            if i_stop - i > CELL_BOX_MIN:
                                if cell_s2_lb(c, rot, ax, splats.cell_box_lo[k_box], splats.cell_box_hi[k_box]) * CELL_BOX_SHRINK > s2_cut:
                                    i = i_stop
                                    continue
                        for si in range(i, i_stop):
                            if ncol > k_collide:
                                break
                            d = splats.means[si] - c
                            dd = wp.dot(d, d)
                            if dd <= rho2:
                                ns = splat_inflation(splats, p, si)
                                if ns >= 0.0:
                                    test = True
                                    if scan:
                                        s2p = plain_s2(d, dd, a, sphere, inv_r2)
                                        min_s2 = wp.min(min_s2, s2p)
                                        test = s2p <= s2_cut1  # (else s2~ >= 1 by the radius bound)
                                    if test:
                                        if link_s2(d, dd, a, sphere, inv_r2, splats.mrows, si, ns, s2_cut1, p.lin_distance) < 1.0:
                                            ncol += 1
                        i = i_stop
        if scan:
            near_slack = wp.min(near_slack, a_min * (wp.sqrt(wp.max(min_s2, 0.0)) - s_star) / s_star)
    if ncol > k_collide:
        return True, float(0.0), True
    sl = wp.max(far_slack, cover_slack)
    if scan:
        sl = wp.max(sl, wp.max(near_slack, 0.0) * DIST_SHRINK)
    return False, sl, True


@wp.kernel
def metric_collide_kernel(
    offset: int,
    links: LinkBatch,
    splats: SplatTiers,
    dgrid: MeanDistanceGrid,  # use == 0: no tier skipped
    p: MetricParams,  # p.cap is ignored: the radius is the one for cap = 1
    out_hit: wp.array(dtype=wp.bool),  # (B,) True in collision (or invalid)
    bad: wp.array(dtype=wp.int32),  # (1,)
    slack: wp.array(dtype=wp.float32),  # (B,) written when want_slack: FREE SLACK (module docstring); want_slack 2: in: the target, out: the RIGID SLACK; else (1,) unused
    want_slack: int,
):
    """Collision-only variant (:func:`link_collides`), one thread per query ellipsoid."""
    q = wp.tid() + offset
    if links.use_order != 0:
        q = links.order[q]
    target = float(0.0)
    if want_slack == 2:
        target = slack[q]
    hit, sl, ok = link_collides(links, q, splats, dgrid, p, want_slack, target)
    out_hit[q] = hit
    if want_slack != 0:
        slack[q] = sl
    if not ok:
        wp.atomic_min(bad, 0, q)


@wp.struct
class RobotGroups:
    """The ellipsoids of a robot in groups that move rigidly together (a link's), for
    :func:`robot_collide_kernel` (GROUP BOUND in the module docstring)."""

    first: wp.array(dtype=wp.int32)  # (G + 1,) group g holds members[first[g]:first[g + 1]]
    members: wp.array(dtype=wp.int32)  # (E,) ellipsoid indices, group by group, in check order
    radius: wp.array(dtype=wp.float32)  # (G,) R_g: a group whose centroid's mean-distance bound exceeds it is free
    reach: wp.array(dtype=wp.float32)  # (E,) per member k (order of members): |c_e - c_g| + rho_top(e) <= R_g, padded
    n_groups: int
    n_ellipsoids: int  # E: the ellipsoids of configuration b are queries b E .. b E + E - 1


@wp.func
def group_bound(links: LinkBatch, groups: RobotGroups, dgrid: MeanDistanceGrid, base: int, g: int):
    """GROUP BOUND of group g of the configuration whose ellipsoids start at ``base``: (its centroid,
    the mean-distance bound there, whether the group is free by it: the bound exceeds R_g plus a pad
    against the float32 rounding of the centroid at its distance from the origin; never without the
    grid, and a NaN centre fails the test)."""
    k0 = groups.first[g]
    k1 = groups.first[g + 1]
    cg = wp.vec3(0.0, 0.0, 0.0)
    for k in range(k0, k1):
        cg = cg + links.centers[base + groups.members[k]]
    cg = cg / float(k1 - k0)
    d = mean_distance_lb(dgrid, cg)
    far = dgrid.use != 0 and d > groups.radius[g] + 1.0e-5 * wp.length(cg)
    return cg, d, far


@wp.func
def config_collides(
    links: LinkBatch,  # the ellipsoids of configuration b at rows b E .. b E + E - 1
    splats: SplatTiers,
    dgrid: MeanDistanceGrid,
    p: MetricParams,
    groups: RobotGroups,
    b: int,
    bad: wp.array(dtype=wp.int32),  # (1,) smallest invalid configuration
    slack: wp.array(dtype=wp.float32),  # rows b E ..: as in robot_collide_kernel
    want_slack: int,
):
    """Whether configuration b collides (some ellipsoid collides or is invalid), with its slack
    written as ``want_slack`` asks: the body of :func:`robot_collide_kernel`, for kernels that
    check configurations they compute themselves."""
    base = b * groups.n_ellipsoids
    if want_slack == 1:
        for e in range(groups.n_ellipsoids):
            slack[base + e] = 0.0
    hit = bool(False)
    stop = bool(False)  # an invalid link: left to the pass below (it reports it)
    if dgrid.use_ub != 0 and p.k_collide == 0:  # HIT BOUND first: a configuration with a link on a mean ends at one read per near link
        for g in range(groups.n_groups):
            k0 = groups.first[g]
            k1 = groups.first[g + 1]
            cg, d, far = group_bound(links, groups, dgrid, base, g)
            if far:
                continue  # (a free group: see below)
            for k in range(k0, k1):
                q = base + groups.members[k]
                c = links.centers[q]
                ax = links.axes[q % links.axes_period]
                if not link_valid(links, q, c, ax):
                    stop = True
                    break
                if hit_bound(dgrid, p, c, wp.min(ax)):
                    hit = True
                    break
            if hit or stop:
                break
    ratio = float(1.0)  # RIGID SLACK: the smallest slack / target so far (no later link needs more than that share of its target)
    for g in range(groups.n_groups):
        if hit:  # (found by the HIT BOUND pass)
            break
        k0 = groups.first[g]
        k1 = groups.first[g + 1]
        cg, d, far = group_bound(links, groups, dgrid, base, g)
        if far:
            if want_slack != 0:  # each member's own reach (<= R_g): its slack is at least the group's
                for k in range(k0, k1):
                    q = base + groups.members[k]
                    sl = (d - groups.reach[k] - 1.0e-5 * wp.length(cg)) * DIST_SHRINK
                    if want_slack == 2:  # RIGID SLACK: a member with less than its target is scanned for more
                        target = slack[q]
                        if sl < target * ratio:
                            h, sl2, ok = link_collides(links, q, splats, dgrid, p, want_slack, target * ratio)
                            if not h:  # (proven free by the group bound: h is False)
                                sl = wp.max(sl, sl2)
                        if target > 0.0:
                            ratio = wp.min(ratio, sl / target)
                    slack[q] = sl
            continue
        for k in range(k0, k1):
            q = base + groups.members[k]
            target = float(0.0)
            if want_slack == 2:
                target = slack[q]
            h, sl, ok = link_collides(links, q, splats, dgrid, p, want_slack, target * ratio)
            if want_slack == 2 and target > 0.0:
                ratio = wp.min(ratio, sl / target)
            if want_slack != 0:
                slack[q] = sl
            if not ok:
                wp.atomic_min(bad, 0, b)
            if h:
                hit = True
                break
        if hit:
            break
    if hit and want_slack == 2:  # (the targets of the members not reached)
        for e in range(groups.n_ellipsoids):
            slack[base + e] = 0.0
    return hit


@wp.kernel
def robot_collide_kernel(
    offset: int,
    links: LinkBatch,  # (B E,) the ellipsoids of B configurations, configuration-major
    splats: SplatTiers,
    dgrid: MeanDistanceGrid,
    p: MetricParams,
    groups: RobotGroups,
    out_hit: wp.array(dtype=wp.bool),  # (B,) True: some ellipsoid of the configuration collides (or is invalid)
    bad: wp.array(dtype=wp.int32),  # (1,) smallest invalid configuration
    slack: wp.array(dtype=wp.float32),  # (B E,) when want_slack: FREE SLACK per ellipsoid (0 where unknown); want_slack 2: in the target, out the RIGID SLACK; else (1,)
    want_slack: int,
):
    """One thread per configuration (:func:`config_collides`): group by group, a group whose
    centroid is farther from every mean than R_g is free (one read), else its ellipsoids are tested
    (:func:`link_collides`); the first colliding ellipsoid ends the configuration (GROUP BOUND in the
    module docstring)."""
    b = wp.tid() + offset
    out_hit[b] = config_collides(links, splats, dgrid, p, groups, b, bad, slack, want_slack)


@wp.func
def edge_sample_fk(
    m: FKModel,
    q: wp.array2d(dtype=wp.float32),
    scratch_rot: wp.array(dtype=wp.mat33),
    scratch_pos: wp.array(dtype=wp.vec3),
    links: LinkBatch,
    starts: wp.array2d(dtype=wp.float64),
    ends: wp.array2d(dtype=wp.float64),
    i: int,
    k: int,
    n: int,
):
    """Sample k of edge i's n, starts + (k / n)(ends - starts) (float64, cast to float32 as the host
    path does), into row i of ``q`` and its ellipsoids' poses into ``links`` (:func:`fk_config`)."""
    t = wp.float64(k) / wp.float64(n)
    for d in range(starts.shape[1]):
        q[i, d] = wp.float32(starts[i, d] + t * (ends[i, d] - starts[i, d]))
    fk_config(m, q, i, scratch_rot, scratch_pos, links.centers, links.rots)


@wp.kernel
def edge_walk_kernel(
    links: LinkBatch,  # (N E,) per edge the ellipsoids of the configuration it checks (scratch, written by its FK)
    splats: SplatTiers,
    dgrid: MeanDistanceGrid,
    p: MetricParams,
    groups: RobotGroups,
    bad: wp.array(dtype=wp.int32),  # (1,) smallest invalid edge
    slack: wp.array(dtype=wp.float32),  # (N E,) scratch: the RIGID SLACK target in, the slack out
    m: FKModel,
    q: wp.array2d(dtype=wp.float32),  # (N, dof) scratch: the configuration edge i checks
    scratch_rot: wp.array(dtype=wp.mat33),  # FK slots, as in fk_kernel
    scratch_pos: wp.array(dtype=wp.vec3),
    starts: wp.array2d(dtype=wp.float64),  # (N, dof) edge starts (not checked)
    ends: wp.array2d(dtype=wp.float64),  # (N, dof) edge ends
    n_samples: wp.array(dtype=wp.int32),  # (N,) n_i >= 1: the check samples a + (k / n_i)(b - a), k = 1..n_i
    step: wp.array2d(dtype=wp.float64),  # (N, E) bound on each ellipsoid's displacement (any point) between consecutive samples
    t_steps: int,  # the slack a check asks for, in samples (>= 1)
    screen: int,  # > 0: first the samples screen, 2 screen, ... < n_i (no slack), stopping at a hit
    out_free: wp.array(dtype=wp.bool),  # (N,) every sample of edge i is free
    out_checks: wp.array(dtype=wp.int32),  # (N,) configurations checked
):
    """One thread per edge: SLACK WALK (:mod:`.edge_walk`): a check ``want`` samples past the
    proven prefix asks for a RIGID SLACK of ``want`` steps; its slack proves the samples within
    floor(min_e slack_e / step_e) of it free. One that reaches the prefix extends it, and the next
    goes one step farther (up to t_steps); one that does not leaves a proven span, and the gap
    before it is filled from its right end, each check asking to reach the prefix (a sample is
    never checked twice). Stops at the first colliding sample (or invalid configuration: reported
    in ``bad``); with ``screen``, a first pass over every screen-th sample stops it sooner where the
    edge collides."""
    i = wp.tid()
    n = n_samples[i]
    ne = groups.n_ellipsoids
    base = i * ne
    lo = int(0)  # samples 1..lo proven free
    want = t_steps  # where the next check goes past the prefix, and the slack it asks for, in samples (0..t_steps)
    span0 = n + 1  # samples span0..span1: proven free by a check that did not reach the prefix
    span1 = int(-1)
    checks = int(0)
    free = bool(True)
    if screen > 0:  # the screen: an edge that collides there costs few checks
        ks = screen
        while ks < n:
            edge_sample_fk(m, q, scratch_rot, scratch_pos, links, starts, ends, i, ks, n)
            checks += 1
            if config_collides(links, splats, dgrid, p, groups, i, bad, slack, 0):
                free = False
                lo = n  # (no walk)
                break
            ks += screen
    while lo < n:
        pk = wp.min(lo + 1 + want, n)
        if span0 <= n:  # a gap before a proven span: filled from its right end (asking to reach the prefix)
            pk = span0 - 1
            want = wp.min(t_steps, pk - lo - 1)
        edge_sample_fk(m, q, scratch_rot, scratch_pos, links, starts, ends, i, pk, n)
        ask = wp.float64(0.0)  # the target in steps: half a step over ``want`` (the kernel returns a capped slack a little short of its target)
        if want > 0:
            ask = wp.float64(want) + wp.float64(0.5)
        for e in range(ne):
            slack[base + e] = wp.float32(step[i, e] * ask)
        checks += 1
        if config_collides(links, splats, dgrid, p, groups, i, bad, slack, 2):
            free = False
            break
        reach = wp.float64(n)  # samples proven on either side (every ellipsoid that moves keeps its slack)
        for e in range(ne):
            st = step[i, e]
            if st > 0.0:
                reach = wp.min(reach, wp.floor(wp.float64(slack[base + e]) / st))
        k = int(wp.max(reach, wp.float64(0.0)))
        if pk - k <= lo + 1:  # it reaches the prefix: the prefix grows past its reach (and the span it meets)
            lo = wp.max(lo, wp.min(pk + k, n))
            if lo + 1 >= span0:
                lo = wp.max(lo, span1)
                span0 = n + 1
            want = wp.min(t_steps, wp.max(k, want + 1))  # (one step more than it asked for, up to t_steps)
        else:  # a gap before it: its span is kept (while filling a gap, pk + 1 == span0: the span grows leftwards)
            if span0 > n:
                span1 = wp.min(pk + k, n)
            span0 = pk - k
    out_free[i] = free
    out_checks[i] = checks


@wp.kernel
def gather_rows_kernel(src: wp.array(dtype=wp.vec3), step: int, dst: wp.array(dtype=wp.vec3)):
    """dst[i] = src[i * step]: an evenly spaced sample of a device array (to size the hash grids)."""
    i = wp.tid()
    dst[i] = src[i * step]


@wp.func
def _spread_bits(v: int):
    """The low 10 bits of v spread to every third bit (Morton interleaving)."""
    x = v & 0x3FF
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    x = (x | (x << 2)) & 0x09249249
    return x


@wp.kernel
def morton_keys_kernel(
    centers: wp.array(dtype=wp.vec3),  # (B,)
    lo: wp.vec3,  # corner of the sorting box (robust scene bounds)
    scale: wp.vec3,  # 1023 / box size per axis
    keys: wp.array(dtype=wp.int32),  # (>= 2B,) 30-bit sort key (below)
    values: wp.array(dtype=wp.int32),  # (>= 2B,) query index
    group_period: int,  # > 1: queries i with the same i % group_period (the same robot ellipsoid) sort together
    shift: int,  # Morton bits dropped per axis to make room for the group index (0 when group_period == 1)
):
    """Key of query i: the Morton code of its clamped 10-bit cell (30 bits), or with groups the group
    index i % group_period above the Morton code of the (10 - shift)-bit cell (3 (10 - shift) bits)."""
    i = wp.tid()
    c = centers[i]
    key = int(0)
    if wp.isfinite(c):
        p = wp.cw_mul(c - lo, scale)
        x = int(wp.clamp(p[0], 0.0, 1023.0)) >> shift
        y = int(wp.clamp(p[1], 0.0, 1023.0)) >> shift
        z = int(wp.clamp(p[2], 0.0, 1023.0)) >> shift
        key = _spread_bits(x) | (_spread_bits(y) << 1) | (_spread_bits(z) << 2)
    if group_period > 1:
        key = key | ((i % group_period) << (3 * (10 - shift)))
    keys[i] = key
    values[i] = i
