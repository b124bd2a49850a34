"""SPLANNING baseline (roahmlab/splanning): Gaussian density integrated over the robot's cube.

Re-implemented from SPEC section 3.4 (no code copied). The scene density is
``rho(x) = sum_i o_i N(x; mu_i, Sigma_i)``. For a robot sphere of radius r at c, each Gaussian is
integrated over the cube of half-width r centred at c and **axis-aligned with the Gaussian's
principal frame** (so the integral separates)::

    d = R^T (mu - c),   inv_k = 1 / s_k^2,   norm_i = 1 / ((2 pi)^{3/2} sqrt(det Sigma_i))
    I_i = o_i * norm_i * prod_k sqrt(pi / (2 inv_k)) * [erf(sqrt(inv_k / 2) (d_k + r))
                                                       - erf(sqrt(inv_k / 2) (d_k - r))]
    I = sum_i I_i,    p = 1 - exp(-I / (4 pi))

``p`` is the native score and is already oriented (larger = more likely in collision). The
released code applies ``R`` to ``mu - c`` where the principal-frame offset needs ``R^T`` (R maps
local to world, its columns are the principal axes); **we use R^T**, as the SPEC asks. The
released code scales by ``1 / alpha`` and thresholds ``p > alpha``; ``alpha`` is a user risk
level (default here 0.01, arbitrary: precision-recall sweeps do not depend on it).

Degenerate scales: 2DGS disks have ``s_3 = 0`` (``inv = inf``, ``det = 0``). All scales are
floored at ``min_scale`` (default :data:`~splatplan.baselines._common.MIN_SCALE` = 1e-7 scene
units) before entering ``inv_k``, ``sqrt(det Sigma)`` and ``sqrt(pi/(2 inv_k))``; the floored disk
is a slab 1e-7 thick, and the s-factors of ``norm_i`` and of the erf prefactors cancel exactly
(``I_i = o_i prod_k 0.5 [erf - erf]``), so the floor only changes the (vanishing) thickness.

Culling: pairs with ``|c - mu_i| > 6 max_k s_ik + r`` contribute 0: the dense [b, n, 3] offset
block is masked and the erf terms are computed for the surviving pairs only.
The cull is not exact: the cube's corners lie r sqrt(3) from c, within ``6 s_max - 0.73 r`` of a
culled mean, so a culled Gaussian may still hold a small tail mass (observed <= 1e-5 per query
with r ~ s); ``cull_std=inf`` disables it.

Batching, as in the original: dense [spheres, Gaussians, 3] tensors. To bound memory the queries
are split into blocks of ``b = min(batch, budget // 3)`` rows and the Gaussians into blocks of
``n = budget // (3 b)`` columns, where ``budget`` is the element cap of
:func:`~splatplan.baselines._common.elem_budget` (on CPU 2**22 elements = 16 MiB per float32
tensor, chosen for speed, so at b = 4096 Gaussians go in blocks of 341; on CUDA 80% of the free
memory over ~6 live tensors), or ``max_elems`` when given. Blocks over Gaussians are summed into I.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch

from ._common import MIN_SCALE, Baseline, as_centers, check_radius, elem_budget, to_numpy

__all__ = ["Splanning", "splanning_score", "collision_score", "collision_from_score", "NATIVE_BATCH", "DEFAULT_ALPHA"]

NATIVE_BATCH = 4096
#: Default risk level: native decision is collision iff ``p > alpha``.
DEFAULT_ALPHA = 0.01
#: Rough number of live [b, n, 3]-sized tensors at the peak (offset, rotated offset, erf terms).
_N_LIVE = 6


class Splanning(Baseline):
    """SPLANNING's collision probability over a fixed scene (tensors precomputed once).

    Args (besides ``splats_or_tensors``, ``device`` and ``dtype``: see :class:`~._common.Baseline`):
        min_scale: floor on the linear scales (2DGS / degenerate splats), scene units.
        cull_std: cull Gaussians farther than ``cull_std * s_max + r`` (6 in SPLANNING).
        max_elems: cap on the elements of one [b, n, 3] block (None: device default).
    """

    native_batch = NATIVE_BATCH
    orientation = 1.0  # p grows with collision
    threshold = DEFAULT_ALPHA

    def __init__(
        self,
        splats_or_tensors: Any,
        device: str | torch.device = "auto",
        min_scale: float = MIN_SCALE,
        cull_std: float = 6.0,
        max_elems: int | None = None,
        dtype: torch.dtype = torch.float32,
    ) -> None:
        super().__init__(splats_or_tensors, device, dtype)
        s = self.scene.scales.clamp_min(float(min_scale))  # [N, 3]
        inv = 1.0 / (s * s)  # [N, 3] inv_k = 1 / s_k^2
        self.erf_scale = (inv / 2.0).sqrt()  # [N, 3] sqrt(inv_k / 2)
        self.prefactor = (math.pi / (2.0 * inv)).sqrt()  # [N, 3] sqrt(pi / (2 inv_k))
        sqrt_det = s.prod(dim=-1)  # [N] sqrt(det Sigma) = s1 s2 s3
        self.weight = self.scene.opacities / ((2.0 * math.pi) ** 1.5 * sqrt_det)  # [N] o_i * norm_i
        self.cull = float(cull_std) * s.max(dim=-1).values  # [N]
        self.rot = self.scene.rotations  # [N, 3, 3] R (local -> world)
        self.max_elems = max_elems

    def blocks(self, batch: int) -> tuple[int, int]:
        """(query rows, Gaussian columns) of one dense block under the memory cap."""
        budget = elem_budget(self.device, self.scene.dtype, _N_LIVE, self.max_elems)
        b = max(1, min(int(batch), budget // 3))
        n = max(1, min(len(self.scene), budget // (3 * b)))
        return b, n

    def integral_torch(self, centers: torch.Tensor, radius: float, cols: int | None = None) -> torch.Tensor:
        """I = sum_i I_i for a [b, 3] block of centres -> [b], Gaussians in blocks of ``cols``."""
        r = check_radius(radius)
        n_all = len(self.scene)
        cols = n_all if cols is None else cols
        total = torch.zeros(centers.shape[0], dtype=centers.dtype, device=centers.device)  # [b]
        for g0 in range(0, n_all, cols):
            sl = slice(g0, g0 + cols)
            diff = self.scene.means[None, sl] - centers[:, None]  # [b, n, 3] mu - c
            keep = diff.square().sum(-1) <= (self.cull[sl][None] + r) ** 2  # [b, n] cull mask
            qi, gi = keep.nonzero(as_tuple=True)  # [m] surviving (query, Gaussian) pairs
            if qi.numel() == 0:
                continue
            gi_all = gi + g0
            d = torch.einsum("mji,mj->mi", self.rot[gi_all], diff[qi, gi])  # [m, 3] R^T (mu - c)
            a = self.erf_scale[gi_all]  # [m, 3] sqrt(inv_k / 2)
            lo = torch.erf((d - r).mul_(a))
            terms = torch.erf(d.add_(r).mul_(a)).sub_(lo).mul_(self.prefactor[gi_all])  # [m, 3]
            total.index_add_(0, qi, terms.prod(dim=-1).mul_(self.weight[gi_all]))  # sum_i I_i
        return total

    @torch.no_grad()
    def integral(self, centers: np.ndarray, radius: float, batch: int | None = None) -> np.ndarray:
        """The opacity-weighted density integral I per centre, float64 (B,)."""
        c = as_centers(centers, self.device, self.scene.dtype)
        rows, cols = self.blocks(self.native_batch if batch is None else batch)
        out = [self.integral_torch(c[i : i + rows], radius, cols) for i in range(0, c.shape[0], rows)]
        return to_numpy(torch.cat(out)) if out else np.zeros(0)

    def score(self, centers: np.ndarray, radius: float, batch: int | None = None) -> np.ndarray:
        """Native score ``p = 1 - exp(-I / (4 pi))`` per centre, float64 (B,); :meth:`collision_score` is ``p`` itself."""
        return -np.expm1(-self.integral(centers, radius, batch) / (4.0 * math.pi))

    def in_collision(self, centers: np.ndarray, radius: float, batch: int | None = None, alpha: float = DEFAULT_ALPHA) -> np.ndarray:
        """Native classifier: bool (B,), ``p > alpha``."""
        return self.decide(self.score(centers, radius, batch), alpha)


def splanning_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Native SPLANNING score ``p = 1 - exp(-I / (4 pi))`` per centre, float64 (B,).
    ``method_kw``: ``min_scale``, ``cull_std``, ``max_elems``, ``dtype`` (constructor) and ``batch``."""
    return Splanning.evaluate(splats_or_tensors, centers, radius, device, **method_kw)


def collision_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Oriented score (larger = collision): ``p`` itself."""
    return Splanning.evaluate(splats_or_tensors, centers, radius, device, oriented=True, **method_kw)


def collision_from_score(score: np.ndarray, alpha: float = DEFAULT_ALPHA) -> np.ndarray:
    """Native decision from the native score: collision iff ``p > alpha``."""
    return Splanning.decide(score, alpha)
