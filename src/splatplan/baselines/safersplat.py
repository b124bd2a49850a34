"""SAFER-Splat baseline (chengine/safer-splat): distance to 1-sigma ellipsoids and a CBF barrier.

Re-implemented from SPEC section 3.2 (no code copied). Each Gaussian i is its 1-sigma ellipsoid
with semi-axes ``e = s`` (linear std, floored at ``min_scale`` for 2DGS disks) in its principal
frame. The robot is a sphere of radius r at c; ``y = R^T (c - mu)`` is the centre in that frame.

Point-to-ellipsoid distance (Eberly, "Distance from a point to an ellipse, an ellipsoid, or a
hyperellipsoid"): the closest surface point is ``x_i = e_i^2 y_i / (T + e_i^2)`` where T solves
``sum_i (e_i y_i / (T + e_i^2))^2 = 1``. Normalised by the smallest semi-axis ``e_k``
(``t = T / e_k^2``, ``r_i = (e_i / e_k)^2``, ``z_i = y_i / e_i``) this is the secular equation::

    F(t) = sum_i (r_i z_i / (t + r_i))^2 - 1 = 0,    x_i / e_i = r_i z_i / (t + r_i)

F decreases on t > -1; its root lies in ``[-1 + |z_k|, -1 + |r * z|]`` (Eberly's bracket), in
``[0, ...]`` for points outside (``|z| > 1``) and in ``(-1, 0]`` for points inside. We bisect 25
times on that bracket (clamped at 0 by the inside/outside side), as SAFER-Splat does.

Inside points: as ``z_k -> 0`` the root tends to -1 and ``z_k / (t + 1)`` is 0/0 (Eberly's
degenerate case, e.g. the centre exactly at the mean). For inside points we therefore take the
k-th coordinate from the surface constraint,
``x_k / e_k = sign(z_k) sqrt(1 - sum_{i != k} (r_i z_i / (t + r_i))^2)`` (sign + for 0), which
is the same point when the root is well resolved and Eberly's degenerate solution in the limit;
every other coordinate is well conditioned (``t + r_i >= r_i - 1 > 0``).

Signed squared distance and barrier: ``phi = +1`` outside, ``-1`` inside,
``h = phi * d^2 - r^2``; native score ``min_i h`` (collision iff < 0). :func:`collision_score`
returns ``-min_i h`` (larger = more likely in collision).

Native batch 1 (one query over all Gaussians); ``batch`` > 1 gives identical values faster.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ._common import MIN_SCALE, Baseline, check_radius

__all__ = ["SaferSplat", "safersplat_score", "collision_score", "collision_from_score", "ellipsoid_distance_torch", "NATIVE_BATCH", "THRESHOLD"]

NATIVE_BATCH = 1
#: Native decision: collision iff ``safersplat_score < THRESHOLD``.
THRESHOLD = 0.0


def ellipsoid_distance_torch(
    y: torch.Tensor,  # [..., N, 3] query in each ellipsoid's principal frame
    e: torch.Tensor,  # [N, 3] semi-axes (> 0)
    n_steps: int = 25,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Euclidean distance from points to axis-aligned ellipsoids by bisection on Eberly's equation.

    Args:
        y: query points in the ellipsoids' principal frames, [..., N, 3].
        e: semi-axes, [N, 3], strictly positive.
        n_steps: bisection steps (25 in SAFER-Splat).

    Returns:
        (d, inside): the unsigned distance [..., N] and a bool mask [..., N], True where
        ``sum (y/e)^2 < 1``.
    """
    tiny = torch.finfo(y.dtype).tiny
    ek = e.min(dim=-1, keepdim=True).values  # [N, 1] smallest semi-axis
    kmask = torch.nn.functional.one_hot(e.argmin(dim=-1), 3).to(torch.bool)  # [N, 3] its axis
    r = (e / ek) ** 2  # [N, 3], >= 1, == 1 on axis k
    z = y / e  # [..., N, 3]
    inside = (z * z).sum(-1) < 1.0  # [..., N]
    rz = r * z
    lo = -1.0 + (z * kmask).sum(-1).abs()  # [..., N]
    hi = -1.0 + rz.norm(dim=-1)
    lo = torch.where(inside, lo, lo.clamp_min(0.0))
    hi = torch.where(inside, hi.clamp_max(0.0), hi)
    for _ in range(n_steps):
        t = 0.5 * (lo + hi)
        q = rz / (t[..., None] + r).clamp_min(tiny)  # [..., N, 3]
        f = (q * q).sum(-1) - 1.0
        pos = f > 0
        lo = torch.where(pos, t, lo)
        hi = torch.where(pos, hi, t)
    t = 0.5 * (lo + hi)
    u = rz / (t[..., None] + r).clamp_min(tiny)  # [..., N, 3] = x / e
    # Inside: axis k from the surface constraint (well defined in Eberly's degenerate case).
    rest = (u * u * (~kmask)).sum(-1)  # [..., N]
    sgn = torch.where((z * kmask).sum(-1) < 0, -1.0, 1.0).to(y.dtype)
    uk = sgn * (1.0 - rest).clamp_min(0.0).sqrt()
    u = torch.where(inside[..., None] & kmask, uk[..., None], u)
    d = (u * e - y).norm(dim=-1)  # [..., N]
    return d, inside


class SaferSplat(Baseline):
    """SAFER-Splat's barrier ``h = phi d^2 - r^2`` over a fixed scene (tensors precomputed once).

    Args (besides ``splats_or_tensors``, ``device`` and ``dtype``: see :class:`~._common.Baseline`):
        n_steps: bisection steps on Eberly's equation (25 as in SAFER-Splat).
        min_scale: floor on the semi-axes (2DGS disks have a zero third scale), scene units.
    """

    native_batch = NATIVE_BATCH
    threshold = THRESHOLD

    def __init__(self, splats_or_tensors: Any, device: str | torch.device = "auto", n_steps: int = 25, min_scale: float = MIN_SCALE, dtype: torch.dtype = torch.float32) -> None:
        super().__init__(splats_or_tensors, device, dtype)
        self.n_steps = int(n_steps)
        self.semi_axes = self.scene.scales.clamp_min(float(min_scale))  # [N, 3]
        self.rot_t = self.scene.rotations.transpose(1, 2).contiguous()  # [N, 3, 3] = R^T

    def barrier_torch(self, centers: torch.Tensor, radius: float) -> torch.Tensor:
        """h = phi d^2 - r^2 for every (centre, Gaussian) of a [b, 3] block -> [b, N]."""
        r = check_radius(radius)
        diff = centers[:, None] - self.scene.means[None]  # [b, N, 3]
        y = torch.einsum("nij,bnj->bni", self.rot_t, diff)  # R^T (c - mu)
        d, inside = ellipsoid_distance_torch(y, self.semi_axes, self.n_steps)
        phi = torch.where(inside, -1.0, 1.0).to(d.dtype)
        return phi * d * d - r * r

    def score_torch(self, centers: torch.Tensor, radius: float) -> torch.Tensor:
        """``min_i h_i`` for a [b, 3] block -> [b] (collision iff < 0; :meth:`collision_score` is ``-min_i h_i``)."""
        return self.barrier_torch(centers, radius).min(dim=-1).values


def safersplat_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Native SAFER-Splat score ``min_i (phi_i d_i^2 - r^2)`` per centre, float64 (B,); collision iff < 0.
    ``method_kw``: ``n_steps``, ``min_scale``, ``dtype`` (constructor) and ``batch``."""
    return SaferSplat.evaluate(splats_or_tensors, centers, radius, device, **method_kw)


def collision_score(splats_or_tensors: Any, centers: np.ndarray, radius: float, device: str | torch.device = "auto", **method_kw) -> np.ndarray:
    """Oriented score (larger = collision): ``-safersplat_score``."""
    return SaferSplat.evaluate(splats_or_tensors, centers, radius, device, oriented=True, **method_kw)


def collision_from_score(score: np.ndarray) -> np.ndarray:
    """Native decision from the native score: collision iff ``min h < 0``."""
    return SaferSplat.decide(score)
