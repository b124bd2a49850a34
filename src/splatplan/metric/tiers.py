"""How the Warp backend bins splats: :class:`TierConfig` (its knobs), the size classes and tiers of
the splats' largest std, and the voxel grid of lower bounds on the distance to the splat means.

Host-side numpy (no Warp): :mod:`.wp_metric` builds its hash grids and the kernels' structs from
these. See :mod:`.wp_metric` for what size classes and tiers are and :mod:`.wp_metric_kernel` for
the exactness argument.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._config import bounded, check_config

__all__ = ["TierConfig", "cell_boxes", "finer_cell_steps", "mean_distance_bounds", "mean_distance_upper", "quantile_tiers", "size_class_tiers"]


@dataclass
class TierConfig:
    """Performance knobs of the Warp backend: how splats are binned into tiers, grid cells, query
    order (results are exact, and identical, either way)."""

    #: "size": geometric size classes of the largest std (default); "quantile": tiers split at
    #: ``quantiles`` of the largest std (the old scheme, kept for comparison).
    mode: str = bounded("size", choices=("size", "quantile"))
    #: Size classes are [s0 f^k, s0 f^(k+1)) of the largest std, f = class_factor, s0 = the smallest std.
    class_factor: float = bounded(2.0, gt=1)
    #: A class with fewer splats than this merges into the next larger class when that class is
    #: adjacent (at most one factor apart); far larger classes are never merged with it.
    min_tier_count: int = bounded(256, ge=0)
    #: At most this many size classes: the adjacent pair whose merge widens fewest splats' radius merges first.
    max_tiers: int = bounded(16, ge=1)
    #: Fixed cost of one tier per query, in splat visits (a grid probe of ~27 cells). For each query
    #: size, adjacent classes whose search radii are so close that a separate tier would not pay
    #: for itself are searched as one tier (a dynamic programme over the estimated cost).
    tier_overhead: float = bounded(64.0, ge=0)
    #: mode "quantile": quantiles of the per-splat largest std that separate the tiers.
    quantiles: tuple[float, ...] = bounded((0.9, 0.999), gt=0, lt=1)
    #: Hash-grid cell width as a fraction of the tier's query radius.
    cell_factor: float = bounded(1.5, gt=0)  # measured best on Stonehenge (CPU): 0.75-2.0 within 25%
    #: Cell width factor of queries whose typical link is elongated (median a_max >= 1.5 median a_min):
    #: the kernels bound such links' reads by the link box (full queries also clip each row of cells to
    #: the link's ellipsoid), much tighter than the ball, so finer cells pay (Panda MPPI rollouts on the
    #: 200k-splat tabletop, CPU: 0.25 is 1.5x faster than 0.5 and 2.5x faster than 1.0; 0.18-0.35 within
    #: 15%; Panda collides_robot 1.7x faster than with cell_factor).
    elongated_cell_factor: float = bounded(0.25, gt=0)
    #: Largest grid dimension per axis (cells wrap around beyond it; results stay exact).
    max_dim: int = bounded(128, ge=1)
    #: Process the queries of a batch in Morton (Z-curve) order of their centres (a key kernel and a
    #: radix sort on the device), so neighbouring threads read neighbouring splats: ~1.3x on CPU.
    sort_queries: bool = True
    #: ... for batches of at least this many queries.
    sort_min_batch: int = bounded(1024, ge=0)
    #: ... also for ``collides_robot`` (the collision-only kernel on robot batches). Off by default: a
    #: robot batch comes in configuration order (the E ellipsoids of one configuration, then the next;
    #: an RRT's edge samples one after the other), already close in space, and on CPU the sort costs
    #: more than it saves (MBM Panda edge checks, one thread: 59 spheres 17 -> 9.5 us per configuration
    #: without it, 11 fitted ellipsoids 9.2 -> 8.1 us).
    sort_robot_collides: bool = False
    #: Sort a robot batch (semi-axes repeating with a period of at most 512 ellipsoids: ``query_robot``)
    #: by ellipsoid first, then Morton order, so that neighbouring threads (a GPU warp) hold the same
    #: link, whose work per query is alike (Panda near the table: 1 to 300 cell rows per query by link).
    #: The outputs do not change. CPU: no measurable effect. CUDA: not measured yet; a count of the
    #: per-thread work (cell rows and splats read; Panda K = 256 batch near the table) predicts 1.7x less
    #: warp time at 1 lane and 1.3x at 8
    #: (``benchmarks/gpu_rates.py --tune-group-links``).
    group_links: bool = False
    #: Threads per query in the full kernel (``query``): lane l takes every lanes-th splat of each
    #: cell run it visits, and a second kernel sums the lanes in order. On a GPU the lanes of a
    #: query run in one warp over the same cells (coalesced reads, even work); on a CPU one thread
    #: per query is best. None = 8 on CUDA, 1 on CPU. Counts and flags are the same for any value,
    #: float sums up to summation order. Extra device memory per call: 28 bytes x lanes per query
    #: (the partial sums; 73 MB for 327k queries at 8 lanes).
    lanes: int | None = bounded(None, ge=1)
    #: The collision-only kernel (``collides``, RRT edge checks) reads, in every cell row holding more
    #: than a few splats, only the cells that the link's ellipsoid can reach (ROW_CLIP of the full
    #: kernel, :mod:`.wp_metric_kernel`); False: whole rows of the link's box.
    collide_row_clip: bool = True
    #: The collision-only kernels first test a link near splats (one the mean-distance bound at its
    #: centre does not clear) with up to 4 spheres along its longest axis that together cover it,
    #: each against the mean-distance bound at its own centre (COVER SPHERES, :mod:`.wp_metric_kernel`):
    #: a link they clear is free without a splat read (the same collision answers and FREE SLACK; its
    #: RIGID SLACK may be larger, a promise that still holds). False: every such link is scanned.
    collide_cover: bool = True
    #: The collision-only kernel skips, in the cell rows it reads, every cell (holding more than a
    #: few splats) whose means' bounding box lies beyond the link's search ellipsoid by a lower
    #: bound from the link's three axes (CELL BOXES, :mod:`.wp_metric_kernel`; same outputs): a
    #: surface patch beside a near link costs one test instead of its splats. Only dense tiers (more
    #: than 16 splats per occupied cell) get boxes, 24 bytes per grid cell, at most the tier's own
    #: splat data (52 bytes a splat).
    collide_cell_boxes: bool = True
    #: ``collides_robot`` (the collision-only kernel on robot batches) uses grids with cells this many
    #: times wider than (elongated_)cell_factor x its radius. Its radius is for cap 1, half the full
    #: query's at the default s2_cap 4, so 2 gives both the same cell width. The best width depends on
    #: the splats per cell: finer cells read fewer splats but cost a probe per cell row of the link box.
    #: Measured per CPU-second, one thread: MBM Panda edge checks (100k splats over a few m^2) the fitted
    #: one-per-link model 1.9x and VAMP's 59 spheres 1.2x faster with 2 than with 1; the Panda on
    #: Stonehenge scaled x4 1.6x faster, at scale 1 (200k splats in 1 m, as dense as it gets) 1.5x
    #: slower. Plain ``collides`` keeps 1: small spheres (r = 1.5 cm at n_sigma 1 on Stonehenge) are
    #: 1.5x slower with 2.
    robot_collide_cell_scale: float = bounded(2.0, gt=0)
    #: ... and finer still where the scene is dense: while a tier's splats fill the cells of that width
    #: with more than this many splats on average (occupied cells only), the width shrinks by a step
    #: of 2^(1/4), at most 4 steps (2x finer) (:func:`finer_cell_steps`; counted once per tier and
    #: width, ~50 ms a step for 500k splats). None: the width above as it is.
    #: Measured per CPU-second, one thread, the MBM Panda grown by its margin on its planners' own
    #: batches (node checks, and edge checks with RIGID SLACK), interleaved: at MBM's default sampling
    #: (3.5 mm, ~500k splats a scene, 145-220 splats per occupied cell at the width above) two steps
    #: finer (57-75 a cell) are 8-14% faster in each family at n_sigma 0 and the same at n_sigma 1,
    #: four steps finer (31-38 a cell) 0-5% slower than two; at 7 mm (120k splats, ~38 a cell) two
    #: steps finer are within 1%; on the built-in tabletop (17-32 a cell) two steps finer are up to 28%
    #: slower at n_sigma 1: the rule leaves both as they are.
    robot_collide_cell_splats: float | None = bounded(80.0, gt=0)
    #: The collision-only kernel skips a tier when a voxel grid of lower bounds on the distance to the
    #: nearest splat mean says every mean is beyond the tier's search radius (MEAN DISTANCE GRID,
    #: :mod:`.wp_metric_kernel`; same outputs). Built once per checker on the first ``collides`` call
    #: (a distance transform on the host; MBM scene, 100k splats: ~0.1 s). Links in free space then
    #: cost one read instead of their cell rows (MBM Panda edge checks ~3x fewer CPU-seconds).
    collide_distance_grid: bool = True
    #: Voxels of that grid at most (cubic voxels over the means' bounding box; 4 bytes each).
    distance_grid_voxels: int = bounded(2**21, ge=1)
    #: The collision-only kernels also read, on the same voxels, an upper bound on the distance to the
    #: nearest mean that counts (opacity options): a link whose smallest semi-axis exceeds it holds
    #: that mean and collides without a splat read (HIT BOUND, :mod:`.wp_metric_kernel`; same outputs,
    #: used with ``k_collide`` 0). Built with the grid above, once per opacity threshold (a distance
    #: transform with nearest indices; MBM scene, 500k splats: ~0.5 s, 4 bytes a voxel). Colliding
    #: configurations of a planner then end at one read (MBM Panda: ~80% of them).
    collide_hit_grid: bool = True

    def validate(self) -> "TierConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)


_GROUP_RADII: dict = {}  # (groups key, largest std, n_sigma) -> (radius (G,), reach (E,)): shared by every checker


def cell_boxes(means: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box of the means of every hash-grid cell: the CELL BOXES of :mod:`.wp_metric_kernel`.

    Args:
        means: (N, 3) float32 splat means in the grids' cell order.
        starts: (M,) int, entry k = the first splat of cell k (cell k holds ``means[starts[k]:starts[k + 1]]``;
            the last entry of each tier's table is its end, and tiers follow each other).

    Returns:
        lo (M, 3), hi (M, 3) float32: per entry, the smallest and largest coordinates of its cell's
        means; (0, 0, 0) for an empty cell and for the last entry (never read as a box).
    """
    st = np.asarray(starts, dtype=np.int64).reshape(-1)
    lo = np.zeros((len(st), 3), dtype=np.float32)
    hi = np.zeros((len(st), 3), dtype=np.float32)
    if len(st) < 2:
        return lo, hi
    m = np.asarray(means, dtype=np.float32).reshape(-1, 3)[: st[-1]]  # (the table covers [st[0], st[-1]))
    full = np.nonzero(st[1:] > st[:-1])[0]  # non-empty cells: the cells between two of them are empty,
    if len(full):  # so each one runs up to the next one's start (the last to st[-1]), as reduceat reduces
        lo[full] = np.minimum.reduceat(m, st[full], axis=0)
        hi[full] = np.maximum.reduceat(m, st[full], axis=0)
    return lo, hi


def finer_cell_steps(points: np.ndarray, width: float, target: float, max_steps: int = 4) -> int:
    """How many steps of 2^(1/4) to shrink a hash-grid cell ``width`` by so that ``points`` (N, 3)
    fill their occupied cells with at most ``target`` points on average: the width shrinks one step
    at a time while the average (cells ``floor(p / width)``, occupied ones only) exceeds ``target``,
    at most ``max_steps`` steps. Counted at each width tried (the average depends on how surfaces
    fall on the cell boundaries, so it is not extrapolated)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0 or not (width > 0 and math.isfinite(width)) or not (target > 0) or len(p) <= target:
        return 0
    for k in range(max_steps + 1):
        w = width * 2.0 ** (-k / 4.0)
        with np.errstate(over="ignore", invalid="ignore"):
            scaled = p / w  # (N, 3) in cells
        if not np.all(np.abs(scaled) < 2.0**52):  # (cells this fine are not countable as integers: stop here)
            return k
        cell = np.floor(scaled).astype(np.int64)  # (N, 3)
        cell -= cell.min(axis=0)
        span = cell.max(axis=0) + 1
        if float(np.prod(span.astype(np.float64))) < 2.0**62:
            n_occ = len(np.unique((cell[:, 2] * span[1] + cell[:, 1]) * span[0] + cell[:, 0]))
        else:  # (a huge span: unique rows instead of flat keys)
            n_occ = len(np.unique(cell, axis=0))
        if len(p) / max(n_occ, 1) <= target:
            return k
    return max_steps


def quantile_tiers(smax: np.ndarray, quantiles: tuple[float, ...]) -> np.ndarray:
    """(N,) tier index per splat: tiers split at quantiles of the largest std (the old scheme)."""
    edges = np.unique(np.quantile(smax, quantiles)) if len(smax) > 1 and len(quantiles) else np.zeros(0)
    return np.searchsorted(edges, smax, side="left")


def size_class_tiers(smax: np.ndarray, factor: float = 2.0, min_count: int = 256, max_tiers: int = 8) -> np.ndarray:
    """(N,) tier index per splat (0 = smallest) from geometric size classes of the largest std.

    Class k holds the splats with std in [s0 f^k, s0 f^(k+1)), s0 = the smallest positive std.
    Classes with fewer than ``min_count`` splats merge upwards into the next non-empty class only
    when it is adjacent (k + 1), so a far larger class (a sky shell) keeps its own tight tier; then
    while there are more than ``max_tiers`` tiers, the adjacent pair whose merge costs least
    (the lower tier's count times the growth of its std bound) merges.
    """
    n = len(smax)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    if factor <= 1.0:
        raise ValueError(f"class_factor must be > 1, got {factor}")
    pos = smax[smax > 0]
    s0 = float(pos.min()) if len(pos) else 1.0
    cls = np.floor(np.log(np.maximum(smax, s0) / s0) / math.log(factor) + 1e-9).astype(np.int64)
    keys, inv, counts = np.unique(cls, return_inverse=True, return_counts=True)
    # groups of classes: [first class, last class, count, max std]
    groups: list[list[Any]] = []
    for j, (k, c) in enumerate(zip(keys, counts)):
        groups.append([int(k), int(k), int(c), float(smax[inv == j].max()), [j]])
    merged: list[list[Any]] = []
    for g in groups:
        if merged and merged[-1][2] < min_count and g[0] == merged[-1][1] + 1:
            p = merged.pop()
            g = [p[0], g[1], p[2] + g[2], max(p[3], g[3]), p[4] + g[4]]
        merged.append(g)
    while len(merged) > max(1, max_tiers):
        # cost of merging tier i into i + 1: its members' std bound grows from s_i to s_{i+1}
        costs = [merged[i][2] * (merged[i + 1][3] / max(merged[i][3], 1e-30)) ** 3 for i in range(len(merged) - 1)]
        i = int(np.argmin(costs))
        a, b = merged[i], merged.pop(i + 1)
        merged[i] = [a[0], b[1], a[2] + b[2], max(a[3], b[3]), a[4] + b[4]]
    tier_of_class = np.empty(len(keys), dtype=np.int64)
    for t, g in enumerate(merged):
        tier_of_class[g[4]] = t
    return tier_of_class[inv]


def mean_distance_bounds(means: np.ndarray, max_voxels: int = 2**21, pad: float = 0.25):
    """Per-voxel lower bounds on the distance to the nearest of ``means`` (N, 3) (float32 world
    coordinates, as the kernels hold them): the MEAN DISTANCE GRID of :mod:`.wp_metric_kernel`.

    Cubic voxels of side v over the means' bounding box padded by ``pad`` times its largest side,
    at most ``max_voxels`` of them; voxel (i, j, k) covers ``origin + v [i, i + 1) x [j, j + 1) x
    [k, k + 1)``. Two voxels whose indices differ by (di, dj, dk) are at least
    ``v sqrt(sum max(|d| - 1, 0)^2)`` apart (box to box), which is the Euclidean distance from the
    first voxel's centre to the nearest centre of the 3x3x3 block around the second: so a Euclidean
    distance transform to the occupied voxels dilated by one voxel, times v, bounds the distance
    from every point of a voxel to every mean (at least ``(D - sqrt(3)) v`` for centre distance D);
    stored shrunk by ``1e-4`` relative and ``1e-3 v`` absolute (far above float32 rounding of the
    voxel lookup).

    Returns:
        lb (nz, ny, nx) float32, origin (3,) float32, v (float), box lo (3,) float32, box hi (3,) float32.
    """
    from scipy.ndimage import binary_dilation, distance_transform_edt

    m = np.asarray(means, dtype=np.float32).astype(np.float64)
    box_lo, box_hi = m.min(axis=0), m.max(axis=0)
    p = pad * float((box_hi - box_lo).max())
    lo = (box_lo - p).astype(np.float32).astype(np.float64)  # the grid's corner, exactly as the kernel holds it
    ext = box_hi + p - lo
    tiny = max(float(ext.max()) * 1e-3, 1e-6)
    v = float(np.cbrt(np.prod(ext + tiny) / max(1, max_voxels)))
    v = max(v, tiny)
    while True:
        dims = np.floor(ext / v).astype(np.int64) + 1  # (3,) x, y, z
        if int(np.prod(dims)) <= max_voxels:
            break
        v *= 1.05
    ijk = np.minimum(np.floor((m - lo) / v).astype(np.int64), dims - 1)  # (N, 3)
    occ = np.zeros((int(dims[2]), int(dims[1]), int(dims[0])), dtype=bool)
    occ[ijk[:, 2], ijk[:, 1], ijk[:, 0]] = True
    occ = binary_dilation(occ, structure=np.ones((3, 3, 3), dtype=bool))  # voxels touching an occupied one
    dist = distance_transform_edt(~occ)  # voxels: box-to-box distance to the nearest occupied voxel
    lb = dist * v * (1.0 - 1e-4) - 1e-3 * v
    lb = np.maximum(lb, 0.0).astype(np.float32)
    return lb, lo.astype(np.float32), v, box_lo.astype(np.float32), box_hi.astype(np.float32)


def mean_distance_upper(means: np.ndarray, origin: np.ndarray, v: float, dims_zyx: tuple[int, int, int]) -> np.ndarray:
    """Per-voxel upper bounds on the distance from any point of a voxel to the nearest of ``means``
    (N, 3) (float32 world coordinates), on the voxels of :func:`mean_distance_bounds` (``origin``,
    side ``v``, ``dims_zyx`` (nz, ny, nx)): the HIT BOUND of :mod:`.wp_metric_kernel`.

    Each voxel holding a mean keeps the one closest to its centre; every voxel takes the voxel
    holding a mean whose centre is nearest to its own (a Euclidean distance transform with indices)
    and bounds with that mean m: any point p of the voxel (centre c) has ``|p - m| <= |c - m| +
    v sqrt(3) / 2``. Stored grown by ``1e-4`` relative and ``1e-3 v`` absolute (far above float32
    rounding of the voxel lookup); +inf everywhere when ``means`` is empty.

    Returns:
        ub (nz, ny, nx) float32.
    """
    from scipy.ndimage import distance_transform_edt

    nz, ny, nx = (int(d) for d in dims_zyx)
    m = np.asarray(means, dtype=np.float32).astype(np.float64).reshape(-1, 3)
    if len(m) == 0:
        return np.full((nz, ny, nx), np.inf, dtype=np.float32)
    lo = np.asarray(origin, dtype=np.float64)
    ijk = np.clip(np.floor((m - lo) / v).astype(np.int64), 0, np.array([nx - 1, ny - 1, nz - 1]))  # (N, 3) x, y, z
    flat = (ijk[:, 2] * ny + ijk[:, 1]) * nx + ijk[:, 0]  # (N,)
    off = np.sum((m - (lo + (ijk + 0.5) * v)) ** 2, axis=1)  # (N,) squared distance to the voxel centre
    order = np.argsort(flat + off / (2.0 * v * v), kind="stable")  # by voxel, the closest mean first (off / (2 v^2) <= 3/8 < 1)
    first = order[np.concatenate([[True], flat[order][1:] != flat[order][:-1]])]  # (K,) one mean per occupied voxel
    rep = np.zeros((3, nz * ny * nx), dtype=np.float32)  # per voxel holding a mean: that mean relative to the grid's corner
    rep[:, flat[first]] = (m[first] - lo).T
    empty = np.ones(nz * ny * nx, dtype=bool)
    empty[flat[first]] = False
    ind = distance_transform_edt(empty.reshape(nz, ny, nx), return_distances=False, return_indices=True)  # (3, nz, ny, nx) z, y, x
    near = ((ind[0] * ny + ind[1]) * nx + ind[2]).reshape(-1)  # (nz ny nx,) the voxel holding the nearest mean's index
    del ind
    cx = ((np.arange(nx) + 0.5) * v).astype(np.float32)
    cy = ((np.arange(ny) + 0.5) * v).astype(np.float32)
    cz = ((np.arange(nz) + 0.5) * v).astype(np.float32)
    d2 = (rep[0][near].reshape(nz, ny, nx) - cx[None, None, :]) ** 2
    d2 += (rep[1][near].reshape(nz, ny, nx) - cy[None, :, None]) ** 2
    d2 += (rep[2][near].reshape(nz, ny, nx) - cz[:, None, None]) ** 2
    # float32 arithmetic here: relative error ~1e-6 of the grid's extent, far below the growth margins below
    ub = (np.sqrt(d2, dtype=np.float64) + 0.5 * math.sqrt(3.0) * v) * (1.0 + 1e-4) + 1e-3 * v
    return ub.astype(np.float32)
