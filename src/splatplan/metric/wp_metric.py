"""Glue around the Warp kernels: size classes and tiers, hash grids, multi-core CPU launches.

Size classes and tiers (see :mod:`.wp_metric_kernel` for the exactness argument): splats are
sorted into geometric size classes of their largest std ``sigma`` (classes a factor
``class_factor`` apart). For each query size (semi-axes, n_sigma, s2_cap) a *grid set* groups
adjacent classes into tiers - one tier per class where the search radii differ enough to pay for
a separate grid probe, merged where they do not (a small dynamic programme over an estimated
cost) - and builds one hash grid per tier whose radius comes from the tier's largest ``sigma``.
So every tier's radius fits its members: the many small splats are searched with a tight radius,
and a class of huge splats far from the robot (the "sky shell" of a phone capture: thousands of
7 m splats on a 240 m sphere) stays a tier of its own whose grid cells near the robot are empty,
costing one grid probe per query. Nothing is ever dropped. ``TierConfig(mode="quantile")`` keeps
the old tiers at quantiles of ``sigma`` for comparison. Memory is O(N) per grid set plus O(B) per
batch; at most four grid sets are cached.

Thread safety: the grid cache is guarded by a lock, and launches only read shared data, so two
threads may query one :class:`WarpMetric` (or checker) at once. The CPU thread pool belongs to the
object, is created on first use and shut down by :meth:`WarpMetric.close` (or garbage collection).
"""

from __future__ import annotations

import math
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .._warp import cpu_threads, launch_split, resolve_device
from .._warp import wp as _wp
from ..scenes.splats import Splats, quat_to_rotmat
from .config import COST_REDUCE_CODES, MetricConfig
from .reference import search_radius_ref
from .tiers import TierConfig, cell_boxes, finer_cell_steps, mean_distance_bounds, mean_distance_upper, quantile_tiers, size_class_tiers
from .wp_metric_kernel import (
    CELL_BOX_MIN,
    LanePartials,
    LinkBatch,
    MeanDistanceGrid,
    MetricOutputs,
    MetricParams,
    SplatTiers,
    metric_collide_kernel,
    metric_full_kernel,
    metric_lanes_combine_kernel,
    morton_keys_kernel,
    RobotGroups,
    robot_collide_kernel,
)

wp = _wp()

#: CPU launches per worker thread for one batch (dynamic load balancing).
CHUNKS_PER_THREAD = 8
#: per-configuration launches (``collides_configs``): batches of fewer configurations run on the calling
#: thread, larger ones in chunks of at least CONFIG_MIN_STEP (handing chunks to the pool costs more than it saves below a few
#: hundred configurations: MBM Panda near surfaces, 90 configurations, 0.14 ms on one thread against 0.28 ms on two)
CONFIG_MIN_SPLIT = 256
CONFIG_MIN_STEP = 64
#: relative pad of the GROUP BOUND's radii against float32 rounding (:mod:`.wp_metric_kernel`)
GROUP_PAD = 1.0 + 1e-4

_GROUP_RADII: dict = {}  # (groups key, largest std, n_sigma) -> (radius (G,), reach (E,)): shared by every checker


def _group_radii(key: bytes, first: np.ndarray, members: np.ndarray, rel: np.ndarray, ax: np.ndarray, s_top: float, n_sigma: float):
    """GROUP BOUND radii (float64, unpadded): R_g (G,) and each member's reach |c_e - c_g| + rho_top(e)
    (E,, member order); cached across checkers (a new scene with the same robot and largest std
    reuses them; every scene has its own largest std, so a miss must be cheap: the radii in numpy)."""
    ck = (key, s_top, n_sigma)
    hit = _GROUP_RADII.get(ck)
    if hit is None:
        ax = np.asarray(ax, dtype=np.float64)  # (E, 3)
        rho = search_radius_ref(n_sigma, s_top, ax.min(axis=1), ax.max(axis=1), 1.0)  # (E,)
        reach = (rel + rho)[members]
        hit = (np.array([np.max(reach[first[g] : first[g + 1]]) for g in range(len(first) - 1)]), reach)
        if len(_GROUP_RADII) >= 64:
            _GROUP_RADII.clear()
        _GROUP_RADII[ck] = hit
    return hit



@dataclass
class _GridSet:
    """One hash grid per tier plus the splat data permuted into the grids' cell order."""

    tiers: SplatTiers  # the kernel's view of it (cell tables per tier, splats in cell order)
    groups: tuple  # (first, last) size class of each tier
    counts: list  # splats per tier
    sigma: list  # largest std per tier


def metric_params(cfg: MetricConfig, pow_m: int, collide_clip: bool = False, collide_cover: bool = False) -> MetricParams:
    """The kernels' struct for ``cfg``."""
    p = MetricParams()
    p.n_sigma = float(cfg.n_sigma)
    p.cap = float(cfg.s2_cap)
    p.softmin_t = float(cfg.softmin_t)
    p.softmin_mean = 1 if cfg.softmin_mode == "mean" else 0
    p.d_max = float(cfg.cost_d_max)
    p.gamma = float(cfg.cost_gamma)
    p.s_min = float(cfg.cost_s_min)
    p.reduce_code = COST_REDUCE_CODES[cfg.cost_reduce]
    p.pow_m = int(pow_m)
    p.k_collide = int(cfg.k_collide)
    p.opacity_min = float(cfg.opacity_min)
    p.opacity_scaled = 1 if cfg.opacity_scaled_inflation else 0
    p.use_opacity = 1 if (cfg.opacity_min > 0 or cfg.opacity_scaled_inflation) else 0
    p.collide_clip = 1 if collide_clip else 0
    p.collide_cover = 1 if collide_cover else 0
    p.lin_distance = 1 if cfg.linearize == "distance" else 0
    return p


def _softmin_power(cfg: MetricConfig) -> int:
    """m when softmin_t = m * cost_gamma for a small integer m (and no overflow risk), else 0.

    Then every softmin term exp(-t (v - pivot)) is the m-th power of the cost's
    exp(-gamma (v - s_min)) times a per-pivot factor: one exp per neighbour instead of two.
    """
    if cfg.cost_gamma <= 0:
        return 0
    m = cfg.softmin_t / cfg.cost_gamma
    ok = abs(m - round(m)) < 1e-9 and 1 <= round(m) <= 8 and cfg.cost_gamma * max(cfg.cost_s_min, cfg.s2_cap) < 60.0
    return int(round(m)) if ok else 0


class WarpMetric:
    """Scene data on one Warp device, cached hash grids and a CPU thread pool; see :class:`CollisionChecker`."""

    def __init__(self, scene: Splats, device: str | None = "auto", tiers: TierConfig | None = None) -> None:
        self.device = resolve_device(device)
        self.tiers = tiers or TierConfig()
        self._lp_one: LanePartials | None = None  # placeholders of the one-lane launch (_lane_partials)
        means = scene.means.astype(np.float64)
        scales = scene.scales.astype(np.float64)
        smax = scales.max(axis=1)  # (N,)

        if self.tiers.mode == "size":
            tier_of = size_class_tiers(smax, self.tiers.class_factor, self.tiers.min_tier_count, self.tiers.max_tiers)
        elif self.tiers.mode == "quantile":
            tier_of = quantile_tiers(smax, self.tiers.quantiles)
        else:
            raise ValueError(f"unknown tier mode {self.tiers.mode!r}: use 'size' or 'quantile'")
        # classes: contiguous ranges of the class-sorted splat arrays, sigma increasing
        order_parts, self.class_offset, self.class_count, self.class_sigma, ext = [], [], [], [], []
        start = 0
        for j in range(int(tier_of.max()) + 1):
            idx = np.flatnonzero(tier_of == j)
            if len(idx) == 0:
                continue
            order_parts.append(idx)
            self.class_offset.append(start)
            self.class_count.append(len(idx))
            self.class_sigma.append(float(smax[idx].max()))
            # robust extent (5-95 percentile box): outliers must not make a class look sparse
            m = means[idx]
            ext.append(np.subtract(*np.percentile(m, [95.0, 5.0], axis=0)) if len(idx) >= 20 else m.max(0) - m.min(0))
            start += len(idx)
        self.class_extent = np.asarray(ext)  # (C, 3) bounding-box size of each class's means
        order = np.concatenate(order_parts)
        self.order = order  # class-sorted position -> original splat index

        rot = quat_to_rotmat(scene.quats[order])  # (N, 3, 3)
        self._means_np = means[order].astype(np.float32)  # (N, 3) tier-sorted
        self._mrows_np = (np.transpose(rot, (0, 2, 1)) * scales[order][:, :, None]).astype(np.float32)  # diag(s) R^T
        self._opac_np = np.asarray(scene.opacities, dtype=np.float32)[order]  # (N,) tier-sorted
        # sorting box for the query order: robust bounds of the splat means (a far shell would make it useless)
        blo, bhi = np.percentile(means, [1.0, 99.0], axis=0) if len(means) > 1 else (means.min(0), means.max(0))
        pad = 0.05 * (bhi - blo) + 1e-6
        self._sort_lo = wp.vec3(*(blo - pad).astype(np.float32))
        self._sort_scale = wp.vec3(*(1023.0 / (bhi - blo + 2 * pad)).astype(np.float32))
        self._gridsets: dict[tuple[int, ...], _GridSet] = {}  # quantised cell per tier -> grids + data
        self._keys: dict[tuple[float, ...], tuple[tuple[tuple[int, int], ...], tuple[int, ...]]] = {}  # (n_sigma, cap, a_min, a_max) -> grid key
        self._dense: dict[tuple, int] = {}  # (tier classes, quantised width) -> finer_cell_steps
        self._lock = threading.Lock()
        self._pool: ThreadPoolExecutor | None = None
        self._pool_finalizer: weakref.finalize | None = None
        self._dgrids: dict[float, MeanDistanceGrid] = {}  # opacity threshold -> grid, built on first use (mean_distance_grid)
        self._dgrid_lb: tuple | None = None  # mean_distance_bounds' output (() when off)
        self._dgrid_lb_wp = None  # its lb on the device
        self._no_slack = None  # (1,) placeholder of the collide kernel's slack output
        self._groups_cache: dict = {}  # (robot groups key, largest std, n_sigma) -> RobotGroups
        self._params_cache: dict = {}  # the collide kernels' MetricParams by the config values they are made of

    # ------------------------------------------------------------------ resources
    def executor(self) -> ThreadPoolExecutor:
        """The CPU worker threads of this object's split launches (started on first use)."""
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(max_workers=cpu_threads(), thread_name_prefix="splatplan-metric")
                self._pool_finalizer = weakref.finalize(self, self._pool.shutdown, wait=False)
            return self._pool

    def close(self) -> None:
        """Shut the CPU thread pool down (a later query creates a new one)."""
        with self._lock:
            pool, self._pool = self._pool, None
            if self._pool_finalizer is not None:
                self._pool_finalizer.detach()
                self._pool_finalizer = None
        if pool is not None:
            pool.shutdown(wait=True)

    # ------------------------------------------------------------------ grids
    def grid_key(self, n_sigma: float, cap: float, a_min: float, a_max: float, collide: bool = False) -> tuple:
        """((first, last) class of each tier, quantised (2^(1/4)) cell width of each tier) for a typical
        query with semi-axes in [a_min, a_max]; finer cells (``elongated_cell_factor``) when the typical
        link is elongated (a_max >= 1.5 a_min), whose reads the kernels bound by the link box;
        ``collide``: for ``collides_robot`` (cells ``robot_collide_cell_scale`` times wider)."""
        cf = self.tiers.elongated_cell_factor if a_max >= 1.5 * a_min else self.tiers.cell_factor
        if collide:
            cf *= self.tiers.robot_collide_cell_scale
        args = (float(n_sigma), float(cap), float(a_min), float(a_max), float(cf))
        key = self._keys.get(args)  # memoised
        if key is None:
            # extreme size ratios (a 1e-30 link) give huge radii; any radius beyond 1e30 already makes
            # every grid 1x1x1 (every splat visited), so clamp it there
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                rho_all = search_radius_ref(args[0], np.asarray(self.class_sigma, dtype=np.float64), args[2], args[3], args[1])
            rho = [float(r) if math.isfinite(r) and r < 1e30 else 1e30 for r in np.atleast_1d(rho_all)]
            groups = self._group_classes(rho, cf)
            cells = tuple(int(math.floor(4 * math.log2(max(rho[j] * cf, 1e-9)))) for _, j in groups)
            target = self.tiers.robot_collide_cell_splats
            if collide and target is not None:  # finer cells where the tier is dense
                cells = tuple(q - self._dense_steps(g, q, float(target)) for g, q in zip(groups, cells))
            key = (groups, cells)
            if len(self._keys) >= 256:
                self._keys.clear()
            self._keys[args] = key
        return key

    def _dense_steps(self, group: tuple[int, int], q: int, target: float) -> int:
        """Steps of 2^(1/4) finer than the quantised width 2^(q / 4) for the tier of classes ``group``
        (:func:`~.tiers.finer_cell_steps` with ``target`` = ``TierConfig.robot_collide_cell_splats``;
        memoised: a checker's TierConfig does not change)."""
        key = (group, q)
        hit = self._dense.get(key)
        if hit is None:
            lo = self.class_offset[group[0]]
            n = self.class_offset[group[1]] + self.class_count[group[1]] - lo
            hit = self._dense[key] = finer_cell_steps(self._means_np[lo : lo + n], 2.0 ** (q / 4.0), target)
        return hit

    def _group_classes(self, rho: list[float], cell_factor: float | None = None) -> tuple[tuple[int, int], ...]:
        """Partition of the classes into tiers (contiguous runs) of least estimated cost per query.

        A tier of classes i..j is searched with class j's radius rho_j; class k in it costs about
        n_k * min(1, (2 + cell_factor) rho_j / extent) per axis (the share of its splats in the cells a
        query visits), plus ``tier_overhead`` for the tier. Quantile tiers are never regrouped.
        """
        c = len(rho)
        if self.tiers.mode != "size" or c == 1:
            return tuple((j, j) for j in range(c))
        span = 2.0 + (self.tiers.cell_factor if cell_factor is None else cell_factor)
        n = np.asarray(self.class_count, dtype=np.float64)
        ext = np.maximum(self.class_extent, 1e-12)

        def visits(k: int, r: float) -> float:
            return float(n[k] * np.prod(np.minimum(1.0, span * r / ext[k])))

        best = [0.0] + [math.inf] * c
        cut = [0] * (c + 1)
        for j in range(1, c + 1):
            acc = 0.0
            for i in range(j - 1, -1, -1):  # tier = classes i .. j-1
                acc += visits(i, rho[j - 1])
                v = best[i] + self.tiers.tier_overhead + acc
                if v < best[j]:
                    best[j], cut[j] = v, i
        groups, j = [], c
        while j > 0:
            groups.append((cut[j], j - 1))
            j = cut[j]
        return tuple(reversed(groups))

    def gridset(self, n_sigma: float, cap: float, a_min: float, a_max: float, collide: bool = False) -> _GridSet:
        """Hash grids of every tier for this query radius (cached; safe from several threads;
        ``collide``: those of ``collides_robot``, see :meth:`grid_key`).

        Each grid set keeps its own copy of the splat data in the grid's cell order, so the
        indices a grid returns walk memory almost sequentially (a large win on CPU caches).
        """
        key = self.grid_key(n_sigma, cap, a_min, a_max, collide)
        with self._lock:
            gs = self._gridsets.get(key)
            if gs is None:
                gs = self._build_gridset(key)
                if len(self._gridsets) >= 4:  # bound memory: drop the oldest grid set (users keep theirs alive)
                    self._gridsets.pop(next(iter(self._gridsets)))
                self._gridsets[key] = gs
            return gs

    def _build_gridset(self, key: tuple) -> _GridSet:
        """One cell table per tier: the tier's splats sorted by cell, cell = floor(p / width) mod dims
        (Warp's hash-grid rule, dims <= max_dim per axis), and the start of every cell's run, so a
        query reads each row of cells it covers as one or two contiguous runs."""
        groups, cells = key
        perm, offsets, sigmas, starts, bases, dims_all, inv_ws, cell_lo, cell_hi = [], [0], [], [], [], [], [], [], []
        n_start = 0
        for (ci, cj), q in zip(groups, cells):
            lo = self.class_offset[ci]
            n = self.class_offset[cj] + self.class_count[cj] - lo
            pts = self._means_np[lo : lo + n]
            width = 2.0 ** (q / 4.0)
            inv_w = np.float32(1.0 / width)
            ext = pts.max(0) - pts.min(0)
            # cells past the extent would only wrap around; a radius larger than the extent -> 1x1x1
            dims = np.array([min(self.tiers.max_dim, max(1, math.ceil(e / width) + 1)) for e in ext], dtype=np.int64)
            vcell = np.floor(pts * inv_w).astype(np.int64)  # float32 product, as in the kernel
            cell_lo.append(vcell.min(0))
            cell_hi.append(vcell.max(0))
            cell = np.mod(vcell, dims)
            lin = cell[:, 2] * dims[0] * dims[1] + cell[:, 1] * dims[0] + cell[:, 0]
            local = np.argsort(lin, kind="stable")
            perm.append(lo + local)
            n_cells = int(np.prod(dims))
            counts = np.bincount(lin, minlength=n_cells)
            starts.append(offsets[-1] + np.concatenate([[0], np.cumsum(counts)]))  # (n_cells + 1,) global splat index
            bases.append(n_start)
            n_start += n_cells + 1
            dims_all.append(dims)
            inv_ws.append(inv_w)
            offsets.append(offsets[-1] + n)
            sigmas.append(self.class_sigma[cj])  # classes are sorted by sigma: the last one's is the largest
        cell_perm = np.concatenate(perm)
        d = self.device
        t = SplatTiers()
        sorted_means = self._means_np[cell_perm]  # (N, 3) in the grids' cell order
        t.means = wp.array(sorted_means, dtype=wp.vec3, device=d)
        box_base, box_lo, box_hi = self._cell_boxes(sorted_means, starts, offsets)
        t.box_base = wp.array(box_base, dtype=wp.int32, device=d)
        t.cell_box_lo = wp.array(box_lo, dtype=wp.vec3, device=d)
        t.cell_box_hi = wp.array(box_hi, dtype=wp.vec3, device=d)
        t.mrows = wp.array(self._mrows_np[cell_perm], dtype=wp.mat33, device=d)
        t.opacity = wp.array(self._opac_np[cell_perm], dtype=wp.float32, device=d)
        t.cell_start = wp.array(np.concatenate(starts).astype(np.int32), dtype=wp.int32, device=d)
        t.cell_base = wp.array(np.asarray(bases, np.int32), dtype=wp.int32, device=d)
        t.dims = wp.array(np.asarray(dims_all, np.int32).reshape(-1, 3), dtype=wp.vec3i, device=d)
        t.inv_w = wp.array(np.asarray(inv_ws, np.float32), dtype=wp.float32, device=d)
        t.cell_lo = wp.array(np.clip(np.asarray(cell_lo), -(2**30), 2**30).astype(np.int32).reshape(-1, 3), dtype=wp.vec3i, device=d)
        t.cell_hi = wp.array(np.clip(np.asarray(cell_hi), -(2**30), 2**30).astype(np.int32).reshape(-1, 3), dtype=wp.vec3i, device=d)
        t.offset = wp.array(np.asarray(offsets, np.int32), dtype=wp.int32, device=d)
        t.sigma = wp.array(np.asarray(sigmas, np.float32), dtype=wp.float32, device=d)
        t.n_tiers = len(groups)
        return _GridSet(tiers=t, groups=groups, counts=[b - a for a, b in zip(offsets, offsets[1:])], sigma=sigmas)

    def _cell_boxes(self, sorted_means: np.ndarray, starts: list, offsets: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """CELL BOXES (:mod:`.wp_metric_kernel`) of a grid set: (box_base (T,) int32, lo (M, 3), hi (M, 3)
        float32). A tier gets boxes when ``TierConfig.collide_cell_boxes`` is on, its occupied cells hold
        more than ``CELL_BOX_MIN`` splats on average (the kernel tests no sparser cell) and its boxes
        (24 bytes a cell) are no larger than its splat data (52 bytes a splat); else base -1."""
        base, los, his, m = [], [np.zeros((1, 3), np.float32)], [np.zeros((1, 3), np.float32)], 1  # (entry 0: a placeholder)
        for j, st in enumerate(starts):
            n = int(offsets[j + 1] - offsets[j])
            n_cells = len(st) - 1
            n_occ = int(np.count_nonzero(np.diff(st)))
            if not self.tiers.collide_cell_boxes or n <= CELL_BOX_MIN * max(n_occ, 1) or 24 * n_cells > 52 * n:
                base.append(-1)
                continue
            lo, hi = cell_boxes(sorted_means[offsets[j] : offsets[j + 1]], np.asarray(st) - offsets[j])
            base.append(m)
            los.append(lo)
            his.append(hi)
            m += len(lo)
        return np.asarray(base, np.int32), np.concatenate(los), np.concatenate(his)

    def mean_distance_grid(self, opacity_min: float = 0.0) -> MeanDistanceGrid:
        """The kernels' :class:`MeanDistanceGrid` of the splat means (built once; ``use == 0`` when
        ``TierConfig.collide_distance_grid`` is off; see :func:`mean_distance_bounds`), with the HIT
        BOUND of the means of opacity >= ``opacity_min`` (:func:`mean_distance_upper`; built once per
        threshold, the last few kept; ``use_ub == 0`` when ``TierConfig.collide_hit_grid`` is off)."""
        key = float(np.float32(opacity_min))
        with self._lock:
            hit = self._dgrids.get(key)
            if hit is not None:
                return hit
            d = self.device
            if self._dgrid_lb is None:
                if self.tiers.collide_distance_grid and len(self._means_np):
                    self._dgrid_lb = mean_distance_bounds(self._means_np, int(self.tiers.distance_grid_voxels))
                else:
                    self._dgrid_lb = ()
            g = MeanDistanceGrid()
            g.ub, g.ub_opacity, g.use_ub = self._placeholder_ub(), key, 0
            if self._dgrid_lb:
                lb, origin, v, lo, hi = self._dgrid_lb
                if self._dgrid_lb_wp is None:
                    self._dgrid_lb_wp = wp.array(lb.reshape(-1), dtype=wp.float32, device=d)
                g.lb = self._dgrid_lb_wp
                g.origin, g.inv_v = wp.vec3(*origin), float(np.float32(1.0 / v))
                g.dims = wp.vec3i(int(lb.shape[2]), int(lb.shape[1]), int(lb.shape[0]))
                g.box_lo, g.box_hi, g.use = wp.vec3(*lo), wp.vec3(*hi), 1
                if self.tiers.collide_hit_grid:
                    counted = self._means_np[self._opac_np >= np.float32(key)] if key > 0 else self._means_np
                    g.ub = wp.array(mean_distance_upper(counted, origin, v, lb.shape).reshape(-1), dtype=wp.float32, device=d)
                    g.use_ub = 1
            else:
                g.lb = wp.zeros(1, dtype=wp.float32, device=d)
                g.origin, g.inv_v, g.dims = wp.vec3(0.0, 0.0, 0.0), 1.0, wp.vec3i(1, 1, 1)
                g.box_lo, g.box_hi, g.use = wp.vec3(0.0, 0.0, 0.0), wp.vec3(0.0, 0.0, 0.0), 0
            while len(self._dgrids) >= 3:  # (a checker rarely changes its opacity rule)
                del self._dgrids[next(iter(self._dgrids))]
            self._dgrids[key] = g
            return g

    def _placeholder_ub(self):
        """A one-element HIT BOUND array (never read: ``use_ub == 0``)."""
        return wp.full(1, float("inf"), dtype=wp.float32, device=self.device)

    # ------------------------------------------------------------------ launches
    def _launch(self, kernel, b: int, args: list) -> None:
        """Launch over b queries (kernel inputs ``[offset, *args]``); on CPU several launches per core
        from the checker's pool (:func:`~splatplan._warp.launch_split`)."""
        pool = self.executor() if self.device == "cpu" and cpu_threads() > 1 else None
        launch_split(kernel, b, [0, *args], self.device, pool, min_split=256, min_step=128, chunks_per_thread=CHUNKS_PER_THREAD)

    def sort_queries(self, links: LinkBatch, b: int, keys, values) -> None:
        """Set ``links.order`` to a Morton order of the b query centres (grouped by ellipsoid with
        ``group_links``; int32 scratch ``keys``/``values`` of >= 2b rows)."""
        links.use_order = 0
        if not self.tiers.sort_queries or b < self.tiers.sort_min_batch:
            return
        period, shift = 1, 0
        if self.tiers.group_links and 1 < links.axes_period <= 512 and links.axes_period < b:
            period = links.axes_period
            shift = -(-(period - 1).bit_length() // 3)  # 3 (10 - shift) Morton bits + the group bits <= 30
        wp.launch(morton_keys_kernel, dim=b, inputs=[links.centers, self._sort_lo, self._sort_scale, keys, values, period, shift], device=self.device)
        wp.utils.radix_sort_pairs(keys, values, b, 0, 30)
        links.order = values[:b]
        links.use_order = 1

    @property
    def lanes(self) -> int:
        """Threads per query of the full kernel (:attr:`TierConfig.lanes`, resolved for this device)."""
        n = self.tiers.lanes
        if n is None:
            n = 1 if self.device == "cpu" else 8
        if int(n) < 1:
            raise ValueError(f"TierConfig.lanes must be >= 1, got {n}")
        return int(n)

    def _lane_partials(self, b: int, lanes: int) -> LanePartials:
        """Partial-sum buffers of b queries x lanes; for one lane (never read or written) one
        shared set of 1-element placeholders, so the CPU path allocates nothing per call."""
        if lanes == 1 and self._lp_one is not None:
            return self._lp_one
        lp = LanePartials()
        lp.lanes = lanes
        n = b * lanes if lanes > 1 else 1
        d = self.device
        for name, dt in (("best", wp.float32), ("ncol", wp.int32), ("n_nb", wp.int32), ("pivot", wp.float32), ("acc", wp.float32), ("c_sum", wp.float32), ("c_max", wp.float32)):
            setattr(lp, name, wp.empty(n, dtype=dt, device=d))
        if lanes == 1:
            self._lp_one = lp
        return lp

    def query(self, links: LinkBatch, b: int, a_min: float, a_max: float, cfg: MetricConfig, out: MetricOutputs, scratch=None) -> None:
        """All five outputs of b queries into ``out`` (device arrays of at least b rows); ``scratch``:
        (keys, values) int32 device arrays of >= 2b rows for the query sort (allocated when None)."""
        gs = self.gridset(cfg.n_sigma, cfg.s2_cap, a_min, a_max)
        self.sort_queries(links, b, *(scratch or self._scratch(b)))
        lanes = self.lanes
        lp = self._lane_partials(b, lanes)
        params = metric_params(cfg, _softmin_power(cfg))
        self._launch(metric_full_kernel, b * lanes, [links, gs.tiers, params, out, lp])
        if lanes > 1:
            wp.launch(metric_lanes_combine_kernel, dim=b, inputs=[lp, params, out], device=self.device)

    def collides(self, links: LinkBatch, b: int, a_min: float, a_max: float, cfg: MetricConfig, out_hit, bad, scratch=None, robot_batch: bool = False,
                 slack=None, rigid: bool = False) -> None:  # fmt: skip
        """in_collision of b queries into ``out_hit`` (bool device array of at least b rows);
        ``robot_batch``: the queries are the ellipsoids of robot configurations, in order (not sorted
        unless ``TierConfig.sort_robot_collides``; grids ``robot_collide_cell_scale`` times coarser);
        ``slack``: a float32 device array of at least b rows for each query's FREE SLACK
        (:mod:`.wp_metric_kernel`; 0 everywhere without the mean-distance grid); ``rigid``: the RIGID
        SLACK instead (near splats too)."""
        gs = self.gridset(cfg.n_sigma, 1.0, a_min, a_max, collide=robot_batch)
        if robot_batch and not self.tiers.sort_robot_collides:
            links.use_order = 0  # a robot batch (collides_robot): kept in configuration order
        else:
            self.sort_queries(links, b, *(scratch or self._scratch(b)))
        dgrid = self.mean_distance_grid(cfg.opacity_min)
        slack_arr, want = self.slack_output(slack, rigid)
        params = metric_params(cfg, 0, self.tiers.collide_row_clip, self.tiers.collide_cover)
        self._launch(metric_collide_kernel, b, [links, gs.tiers, dgrid, params, out_hit, bad, slack_arr, want])

    def collides_configs(self, links: LinkBatch, b: int, groups, a_min: float, a_max: float, cfg: MetricConfig, out_hit, bad, slack=None,
                         rigid: bool = False) -> None:  # fmt: skip
        """Per-configuration collision of b configurations (``robot_collide_kernel``): ``links`` holds
        their B E ellipsoids configuration-major, ``groups`` the robot's :func:`~.checker.robot_groups`;
        ``out_hit`` (>= b rows) gets any-ellipsoid-collides, ``slack`` (>= b E rows, optional) each
        ellipsoid's FREE SLACK (``rigid``: the RIGID SLACK). Grids as :meth:`collides` with ``robot_batch``."""
        self.launch_configs(b, self.configs_args(links, groups, a_min, a_max, cfg, out_hit, bad, slack, rigid))

    def configs_args(self, links: LinkBatch, groups, a_min: float, a_max: float, cfg: MetricConfig, out_hit, bad, slack=None, rigid: bool = False) -> list:
        """The inputs of ``robot_collide_kernel`` after its launch offset, for :meth:`collides_configs`
        (arguments as there; grids, groups and parameters cached). The list holds every array the
        kernel reads: a launch recorded with it stays valid while the list is kept."""
        gs = self.gridset(cfg.n_sigma, 1.0, a_min, a_max, collide=True)
        links.use_order = 0
        rg = self.robot_groups(groups, gs, cfg.n_sigma)
        slack_arr, want = self.slack_output(slack, rigid)
        pk = (cfg.n_sigma, cfg.s2_cap, cfg.softmin_t, cfg.softmin_mode, cfg.cost_d_max, cfg.cost_gamma, cfg.cost_s_min, cfg.cost_reduce,
              cfg.k_collide, cfg.opacity_min, cfg.opacity_scaled_inflation, cfg.linearize, self.tiers.collide_row_clip, self.tiers.collide_cover)  # every field metric_params reads
        params = self._params_cache.get(pk)
        if params is None:
            params = metric_params(cfg, 0, self.tiers.collide_row_clip, self.tiers.collide_cover)
            self._params_cache = {pk: params}  # (one entry: the config in use)
        return [links, gs.tiers, self.mean_distance_grid(cfg.opacity_min), params, rg, out_hit, bad, slack_arr, want]

    def launch_configs(self, b: int, args: list) -> None:
        """``robot_collide_kernel`` over b configurations with :meth:`configs_args`' inputs; on CPU
        split over the checker's threads."""
        pool = self.executor() if self.device == "cpu" and cpu_threads() > 1 else None
        # a thread is a whole configuration (tens of ellipsoids): split smaller batches than per-ellipsoid ones
        launch_split(robot_collide_kernel, b, [0, *args], self.device, pool, min_split=CONFIG_MIN_SPLIT, min_step=CONFIG_MIN_STEP,
                     chunks_per_thread=CHUNKS_PER_THREAD)  # fmt: skip

    def slack_output(self, slack, rigid: bool) -> tuple:
        """The collide kernels' (slack array, want_slack): (placeholder, 0) without ``slack``, else
        (slack, 1) for the FREE SLACK or (slack, 2) for the RIGID SLACK (:mod:`.wp_metric_kernel`)."""
        if slack is None:
            return self.no_slack_array(), 0
        return slack, 2 if rigid else 1

    def no_slack_array(self):
        """The (1,) placeholder of the collide kernels' slack output when no slack is asked for."""
        if self._no_slack is None:
            self._no_slack = wp.zeros(1, dtype=wp.float32, device=self.device)
        return self._no_slack

    def robot_groups(self, groups, gs: "_GridSet", n_sigma: float) -> RobotGroups:
        """The kernel's :class:`RobotGroups` for a robot's groups at this grid set and n_sigma
        (cached): R_g = max over members (|c_e - c_g| + rho_top(e)), padded (GROUP BOUND)."""
        key, first, members, rel, ax = groups
        s_top = float(max(gs.sigma)) if len(gs.sigma) else 0.0
        ck = (key, s_top, float(n_sigma))
        with self._lock:
            hit = self._groups_cache.get(ck)
        if hit is not None:
            return hit
        radius, reach = _group_radii(key, first, members, rel, ax, s_top, float(n_sigma))
        rg = RobotGroups()
        rg.first = wp.array(first, dtype=wp.int32, device=self.device)
        rg.members = wp.array(members, dtype=wp.int32, device=self.device)
        rg.radius = wp.array((radius * GROUP_PAD).astype(np.float32), dtype=wp.float32, device=self.device)
        rg.reach = wp.array((reach * GROUP_PAD).astype(np.float32), dtype=wp.float32, device=self.device)
        rg.n_groups = len(first) - 1
        rg.n_ellipsoids = len(members)
        with self._lock:
            if len(self._groups_cache) >= 16:
                self._groups_cache.clear()
            self._groups_cache[ck] = rg
        return rg

    def _scratch(self, b: int):
        n = 2 * b if self.tiers.sort_queries and b >= self.tiers.sort_min_batch else 1
        return wp.empty(n, dtype=wp.int32, device=self.device), wp.empty(n, dtype=wp.int32, device=self.device)
