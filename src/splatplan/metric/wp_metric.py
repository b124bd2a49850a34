"""Glue between numpy and the Warp kernels: scale tiers, hash grids, multi-core CPU launches.

Scale tiers (see :mod:`.wp_metric_kernel` for the exactness argument): splats are binned by
their largest std ``sigma``; each tier gets its own hash grid whose query radius is derived from
the tier's largest ``sigma``, so the many small splats are searched with a tight radius while the
few huge ones (the last tier) get a coarse grid whose cells match their large radius; when that
radius spans the tier's whole extent the grid degenerates to 1x1x1, i.e. every query visits the
tier exhaustively. Nothing is ever dropped. Memory is O(N) for the scene plus O(B) per batch.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .._warp import cpu_threads, resolve_device
from .._warp import wp as _wp
from ..scenes.splats import Splats, quat_to_rotmat
from .config import COST_REDUCE_CODES, MetricConfig, QueryResult
from .reference import link_matrices

wp = _wp()

_POOL: ThreadPoolExecutor | None = None
#: CPU launches per worker thread for one batch (dynamic load balancing).
CHUNKS_PER_THREAD = 8


def _pool() -> ThreadPoolExecutor:
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=cpu_threads(), thread_name_prefix="splatplan-warp")
    return _POOL


@dataclass
class TierConfig:
    """How splats are binned into scale tiers (a performance knob; results are exact either way)."""

    #: Quantiles of the per-splat largest std that separate the tiers.
    quantiles: tuple[float, ...] = (0.9, 0.999)
    #: Hash-grid cell width as a fraction of the tier's query radius.
    cell_factor: float = 1.5  # measured best on Stonehenge (CPU): 0.75-2.0 within 25%
    #: Largest grid dimension per axis (cells wrap around beyond it; results stay exact).
    max_dim: int = 128


@dataclass
class _GridSet:
    """One hash grid per tier plus the splat data permuted into the grids' cell order."""

    grids: list  # wp.HashGrid per tier (kept alive here)
    ids: object  # wp.array(uint64) (T,)
    means: object  # wp.array(vec3) (N,)
    mrows: object  # wp.array(mat33) (N,) diag(s) R^T


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
    """Scene data on one Warp device plus cached hash grids; see :class:`CollisionChecker`."""

    def __init__(self, scene: Splats, device: str | None = "cpu", tiers: TierConfig | None = None) -> None:
        self.device = resolve_device(device)
        self.tiers = tiers or TierConfig()
        means = scene.means.astype(np.float64)
        scales = scene.scales.astype(np.float64)
        smax = scales.max(axis=1)  # (N,)

        # --- tier assignment by quantiles of the largest std
        edges = np.unique(np.quantile(smax, self.tiers.quantiles)) if len(smax) > 1 else np.zeros(0)
        tier_of = np.searchsorted(edges, smax, side="left")  # (N,) in [0, len(edges)]
        n_t = len(edges) + 1
        order_parts, self.tier_offset, self.tier_count, self.tier_sigma = [], [], [], []
        start = 0
        for j in range(n_t):
            idx = np.flatnonzero(tier_of == j)
            if len(idx) == 0:
                continue
            order_parts.append(idx)
            self.tier_offset.append(start)
            self.tier_count.append(len(idx))
            self.tier_sigma.append(float(smax[idx].max()))
            start += len(idx)
        order = np.concatenate(order_parts)
        self.order = order  # tier-sorted position -> original splat index

        rot = quat_to_rotmat(scene.quats[order])  # (N, 3, 3)
        self._means_np = means[order].astype(np.float32)  # (N, 3) tier-sorted
        self._mrows_np = (np.transpose(rot, (0, 2, 1)) * scales[order][:, :, None]).astype(np.float32)  # diag(s) R^T
        self._tier_offset = wp.array(np.asarray(self.tier_offset, np.int32), dtype=wp.int32, device=self.device)
        self._tier_sigma = wp.array(np.asarray(self.tier_sigma, np.float32), dtype=wp.float32, device=self.device)
        self._gridsets: dict[tuple[int, ...], _GridSet] = {}  # quantised cell per tier -> grids + data

    # ------------------------------------------------------------------ grids
    def _gridset(self, n_sigma: float, cap: float, a_min: float, a_max: float) -> "_GridSet":
        """Hash grids of every tier for this query radius (quantised to 2^(1/4), cached).

        Each grid set keeps its own copy of the splat data in the grid's cell order, so the
        indices a grid returns walk memory almost sequentially (a large win on CPU caches).
        """
        key = []
        for sig in self.tier_sigma:
            k = n_sigma * sig / a_min
            rho = a_max * (k + math.sqrt(k * k + cap))
            key.append(int(math.floor(4 * math.log2(max(rho * self.tiers.cell_factor, 1e-9)))))
        key = tuple(key)
        gs = self._gridsets.get(key)
        if gs is not None:
            return gs
        if len(self._gridsets) >= 4:  # bound memory: drop the oldest grid set
            self._gridsets.pop(next(iter(self._gridsets)))
        grids, perm = [], []
        for j, q in enumerate(key):
            lo, n = self.tier_offset[j], self.tier_count[j]
            pts = self._means_np[lo : lo + n]
            width = 2.0 ** (q / 4.0)
            ext = pts.max(0) - pts.min(0)
            # cells past the extent would only wrap around; a radius larger than the extent -> 1x1x1
            dims = np.array([min(self.tiers.max_dim, max(1, math.ceil(e / width) + 1)) for e in ext], dtype=np.int64)
            cell = np.mod(np.floor(pts * np.float32(1.0 / width)).astype(np.int64), dims)  # warp's hashing
            local = np.argsort(cell[:, 2] * dims[0] * dims[1] + cell[:, 1] * dims[0] + cell[:, 0], kind="stable")
            perm.append(lo + local)
            g = wp.HashGrid(*(int(d) for d in dims), device=self.device)
            g.build(wp.array(pts[local], dtype=wp.vec3, device=self.device), width)
            grids.append(g)
        perm = np.concatenate(perm)
        gs = _GridSet(
            grids=grids,
            ids=wp.array(np.asarray([g.id for g in grids], dtype=np.uint64), dtype=wp.uint64, device=self.device),
            means=wp.array(self._means_np[perm], dtype=wp.vec3, device=self.device),
            mrows=wp.array(self._mrows_np[perm], dtype=wp.mat33, device=self.device),
        )
        self._gridsets[key] = gs
        return gs

    # ------------------------------------------------------------------ launches
    def _inputs(self, c: np.ndarray, q: np.ndarray | None, a: np.ndarray):
        b = c.shape[0]
        link_a = link_matrices(q, a, b).astype(np.float32)  # (B, 3, 3)
        mm = np.stack([a.min(1), a.max(1)], axis=1).astype(np.float32)  # (B, 2)
        d = self.device
        return (
            wp.array(c.astype(np.float32), dtype=wp.vec3, device=d),
            wp.array(link_a, dtype=wp.mat33, device=d),
            wp.array(mm, dtype=wp.vec2, device=d),
            float(np.median(mm[:, 0])),
            float(np.median(mm[:, 1])),
        )

    def _launch(self, kernel, b: int, make_inputs) -> None:
        """Launch over b queries; on CPU split into one launch per core (Warp runs a CPU launch on one thread)."""
        n_thr = cpu_threads() if self.device == "cpu" else 1
        if n_thr == 1 or b < 256:
            wp.launch(kernel, dim=b, inputs=make_inputs(0), device=self.device)
            return
        # Several chunks per core, taken from the pool as cores free up: query costs vary a lot
        # (free space vs. dense surfaces), so equal static halves leave a core idle.
        step = max(128, math.ceil(b / (CHUNKS_PER_THREAD * n_thr)))
        futs = [
            _pool().submit(wp.launch, kernel, dim=min(step, b - lo), inputs=make_inputs(lo), device=self.device)
            for lo in range(0, b, step)
        ]
        for f in futs:
            f.result()

    def query(self, c: np.ndarray, q: np.ndarray | None, a: np.ndarray, cfg: MetricConfig) -> QueryResult:
        b = c.shape[0]
        centers, link_a, mm, amin, amax = self._inputs(c, q, a)
        gs = self._gridset(cfg.n_sigma, cfg.s2_cap, amin, amax)
        d = self.device
        out_min = wp.empty(b, dtype=wp.float32, device=d)
        out_ncol = wp.empty(b, dtype=wp.int32, device=d)
        out_soft = wp.empty(b, dtype=wp.float32, device=d)
        out_cost = wp.empty(b, dtype=wp.float32, device=d)
        from .wp_metric_kernel import metric_full_kernel

        pow_m = _softmin_power(cfg)

        def inputs(lo: int):
            return [
                lo, centers, link_a, mm, gs.means, gs.mrows, gs.ids, self._tier_offset, self._tier_sigma,
                len(self.tier_count), float(cfg.n_sigma), float(cfg.s2_cap), float(cfg.softmin_t),
                float(cfg.cost_d_max), float(cfg.cost_gamma), float(cfg.cost_s_min), COST_REDUCE_CODES[cfg.cost_reduce],
                pow_m, out_min, out_ncol, out_soft, out_cost,
            ]  # fmt: skip

        self._launch(metric_full_kernel, b, inputs)
        ncol = out_ncol.numpy()
        return QueryResult(
            min_s2=out_min.numpy(),
            n_colliding=ncol,
            in_collision=ncol > cfg.k_collide,
            softmin=out_soft.numpy(),
            cost=out_cost.numpy(),
        )

    def collides(self, c: np.ndarray, q: np.ndarray | None, a: np.ndarray, cfg: MetricConfig) -> np.ndarray:
        b = c.shape[0]
        centers, link_a, mm, amin, amax = self._inputs(c, q, a)
        gs = self._gridset(cfg.n_sigma, 1.0, amin, amax)
        out_hit = wp.empty(b, dtype=wp.int32, device=self.device)
        from .wp_metric_kernel import metric_collide_kernel

        def inputs(lo: int):
            return [
                lo, centers, link_a, mm, gs.means, gs.mrows, gs.ids, self._tier_offset, self._tier_sigma,
                len(self.tier_count), float(cfg.n_sigma), int(cfg.k_collide), out_hit,
            ]  # fmt: skip

        self._launch(metric_collide_kernel, b, inputs)
        return out_hit.numpy().astype(bool)
