"""ATLASNav baseline (grasp-lyrl/atlasnav), isotropic: 3-sigma balls against a sphere robot.

Re-implemented from SPEC section 3.3 (the original code was not public; neither is ours a copy).
Each splat is replaced by an isotropic Gaussian with ``sigma_i = mean(s_i)`` (the mean of its
three linear scales; a 2DGS disk's zero third scale counts). A point p is occupied for a sphere
of radius r iff ``any_i |p - mu_i| < 3 sigma_i + r``. Native score::

    min_i (|p - mu_i| - 3 sigma_i - r)        (collision iff < 0)

and :func:`collision_score` is its negation (larger = more likely in collision).

Batching, as in the original: a dense (queries x Gaussians) evaluation. We build the explicit
[b, N, 3] difference tensor and its norm (not ``torch.cdist``), which is what makes the original
memory-hungry (SPEC Table: 55 GB at batch 4096 on 200k splats). Queries are split into chunks of
``b = max(1, budget // (3 N))`` rows, where ``budget`` is the element cap of
:func:`~splatplan.baselines._common.elem_budget`, or ``max_elems`` when given. On CUDA the
budget is 80% of the free memory over ~3 live tensors, so batch 4096 runs unchunked whenever it
fits (about 30 GB at N = 200k), i.e. the queries are chunked only as much as memory requires.
On CPU it is 2**22 elements (16 MiB per float32 [b, N, 3] tensor; b = 6 rows at N = 200k),
a size chosen for speed (see :data:`~splatplan.baselines._common.CPU_ELEM_BUDGET`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ._common import Baseline, check_radius, elem_budget

__all__ = ["AtlasNav", "atlasnav_score", "collision_score", "collision_from_score", "NATIVE_BATCH", "THRESHOLD"]

NATIVE_BATCH = 4096
#: Native decision: collision iff ``atlasnav_score < THRESHOLD``.
THRESHOLD = 0.0
#: Rough number of live [b, N, 3]-sized tensors at the peak (difference, its square, slack).
_N_LIVE = 3


class AtlasNav(Baseline):
    """ATLASNav's isotropic occupancy test over a fixed scene.

    Args (besides ``splats_or_tensors``, ``device`` and ``dtype``: see :class:`~._common.Baseline`):
        n_std: ball radius in units of sigma (3 in ATLASNav).
        max_elems: cap on the elements of the [b, N, 3] chunk (None: device default, see module doc).
    """

    native_batch = NATIVE_BATCH
    threshold = THRESHOLD

    def __init__(self, splats_or_tensors: Any, device: str | torch.device = "auto", n_std: float = 3.0, max_elems: int | None = None, dtype: torch.dtype = torch.float32) -> None:
        super().__init__(splats_or_tensors, device, dtype)
        self.sigma = self.scene.scales.mean(dim=-1)  # [N] isotropic std
        self.ball = float(n_std) * self.sigma  # [N]
        self.max_elems = max_elems

    def chunk_rows(self) -> int:
        """Queries per dense [b, N, 3] evaluation under the memory cap."""
        budget = elem_budget(self.device, self.scene.dtype, _N_LIVE, self.max_elems)
        return max(1, budget // (3 * len(self.scene)))

    def rows(self, batch: int) -> int:
        """The caller's ``batch``, split further into :meth:`chunk_rows` rows."""
        return max(1, min(int(batch), self.chunk_rows()))

    def score_torch(self, centers: torch.Tensor, radius: float) -> torch.Tensor:
        """min_i (|p - mu_i| - 3 sigma_i - r) for a [b, 3] block, dense over all Gaussians -> [b]
        (collision iff < 0; :meth:`collision_score` is its negation)."""
        r = check_radius(radius)
        diff = centers[:, None, :] - self.scene.means[None, :, :]  # [b, N, 3]
        dist = diff.square().sum(-1).sqrt()  # [b, N]
        return (dist - self.ball[None] - r).min(dim=-1).values


def atlasnav_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Native ATLASNav score ``min_i (|p - mu_i| - 3 sigma_i - r)``, float64 (B,); collision iff < 0.
    ``method_kw``: ``n_std``, ``max_elems``, ``dtype`` (constructor) and ``batch``."""
    return AtlasNav.evaluate(splats_or_tensors, centers, radius, device, **method_kw)


def collision_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Oriented score (larger = collision): ``-atlasnav_score``."""
    return AtlasNav.evaluate(splats_or_tensors, centers, radius, device, oriented=True, **method_kw)


def collision_from_score(score: np.ndarray) -> np.ndarray:
    """Native decision from the native score: collision iff ``score < 0``."""
    return AtlasNav.decide(score)
