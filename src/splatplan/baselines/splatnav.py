"""Splat-Nav baseline (chengine/splatnav): sphere vs. 1-sigma ellipsoid intersection test.

Re-implemented from SPEC section 3.1 (no code copied). Each Gaussian i is its 1-sigma ellipsoid
``{x : (x - mu)^T Sigma^-1 (x - mu) <= level}``, i.e. the splat with scales ``s * sqrt(level)``.
The robot is a sphere of radius r centred at c. With ``v = R^T (mu - c)`` (the offset in the
Gaussian's principal frame), ``lambda_j = level * s_j^2`` and ``kappa = r^2``::

    K(t) = sum_j v_j^2 t (1 - t) / (kappa + t (lambda_j - kappa)),   t in [0, 1]

is concave in t; the two ellipsoids are disjoint iff ``max_t K(t) > 1``, so a Gaussian is
**in collision iff max_t K(t) < 1** (ties at exactly 1 are tangent contact). The maximum is found
by 10 bisection steps on the sign of::

    dK/dt = sum_j v_j^2 [kappa - 2 t kappa - t^2 (lambda_j - kappa)] / (kappa + t (lambda_j - kappa))^2

The native score is ``min_i max_t K_i`` (collision iff < 1); :func:`collision_score` returns its
negation so that larger means "more likely in collision".

The original evaluates one query at a time over all Gaussians (native batch 1); so do we by
default. ``batch`` > 1 groups queries into one [batch, N, 3] evaluation with identical results,
which only makes large precision-recall sweeps affordable; throughput numbers use batch 1.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ._common import Baseline, check_radius

__all__ = ["SplatNav", "splatnav_score", "collision_score", "collision_from_score", "max_k_torch", "NATIVE_BATCH", "THRESHOLD"]

#: Queries per evaluation in the original code base.
NATIVE_BATCH = 1
#: Native decision: collision iff ``splatnav_score < THRESHOLD``.
THRESHOLD = 1.0


def max_k_torch(
    v2: torch.Tensor,  # [..., N, 3] squared offsets in the principal frame
    lam: torch.Tensor,  # [N, 3] ellipsoid eigenvalues level * s^2
    kappa: float,  # r^2
    n_steps: int = 10,
) -> torch.Tensor:
    """max over t in [0, 1] of K(t) by bisection on the sign of dK/dt.

    Args:
        v2: squared components of ``R^T (mu - c)``, [..., N, 3].
        lam: eigenvalues of the (level-scaled) covariance, [N, 3].
        kappa: squared sphere radius (> 0, so every denominator is > 0 for t in (0, 1)).
        n_steps: bisection steps (10 in Splat-Nav; t is then known to 2^-11).

    Returns:
        [..., N] the value of K at the midpoint of the final bracket.
    """
    lo = torch.zeros(v2.shape[:-1], dtype=v2.dtype, device=v2.device)  # [..., N]
    hi = torch.ones_like(lo)
    dl = lam - kappa  # [N, 3]
    for _ in range(n_steps):
        t = 0.5 * (lo + hi)
        tt = t[..., None]  # [..., N, 1]
        den = kappa + tt * dl  # [..., N, 3]
        dk = (v2 * (kappa - 2.0 * tt * kappa - tt * tt * dl) / (den * den)).sum(-1)  # [..., N]
        rising = dk > 0
        lo = torch.where(rising, t, lo)
        hi = torch.where(rising, hi, t)
    t = 0.5 * (lo + hi)
    tt = t[..., None]
    return (v2 * (tt * (1.0 - tt)) / (kappa + tt * dl)).sum(-1)


class SplatNav(Baseline):
    """Splat-Nav's sphere-ellipsoid test over a fixed scene (tensors precomputed once).

    Args (besides ``splats_or_tensors``, ``device`` and ``dtype``: see :class:`~._common.Baseline`):
        level: ellipsoid level k; the ellipsoid is the splat with scales ``s * sqrt(k)`` (1 = 1 sigma).
        n_steps: bisection steps on dK/dt (10 as in Splat-Nav).
    """

    native_batch = NATIVE_BATCH
    threshold = THRESHOLD

    def __init__(self, splats_or_tensors: Any, device: str | torch.device = "auto", level: float = 1.0, n_steps: int = 10, dtype: torch.dtype = torch.float32) -> None:
        super().__init__(splats_or_tensors, device, dtype)
        self.level = float(level)
        self.n_steps = int(n_steps)
        self.lam = self.level * self.scene.scales**2  # [N, 3]
        self.rot_t = self.scene.rotations.transpose(1, 2).contiguous()  # [N, 3, 3] = R^T

    def score_torch(self, centers: torch.Tensor, radius: float) -> torch.Tensor:
        """min_i max_t K_i for a [b, 3] block of centres, all evaluated together -> [b]
        (collision iff < 1; :meth:`collision_score` is its negation)."""
        kappa = check_radius(radius) ** 2
        diff = self.scene.means[None] - centers[:, None]  # [b, N, 3]
        v = torch.einsum("nij,bnj->bni", self.rot_t, diff)  # R^T (mu - c), [b, N, 3]
        k = max_k_torch(v * v, self.lam, kappa, self.n_steps)  # [b, N]
        return k.min(dim=-1).values


def splatnav_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Native Splat-Nav score ``min_i max_t K_i`` per centre, float64 (B,); collision iff < 1.
    ``method_kw``: ``level``, ``n_steps``, ``dtype`` (constructor) and ``batch`` (see :class:`SplatNav`)."""
    return SplatNav.evaluate(splats_or_tensors, centers, radius, device, **method_kw)


def collision_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Oriented score (larger = collision): ``-splatnav_score``."""
    return SplatNav.evaluate(splats_or_tensors, centers, radius, device, oriented=True, **method_kw)


def collision_from_score(score: np.ndarray) -> np.ndarray:
    """Native decision from the native score: collision iff ``score < 1``."""
    return SplatNav.decide(score)
