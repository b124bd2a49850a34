"""A weight-free encoder: the normalised low-resolution image itself (not a learned feature).

e = flatten(T) standardised per image over all its values, divided by sqrt(D), where T is the
(s, s, 3) area-averaged thumbnail, so ||e|| = 1 (0 for a constant image) and
``||e_t - e_r||^2 = 2 (1 - corr(T_t, T_r))``: invariant to brightness offset and contrast gain
(I -> a I + b, a > 0, before clamping), sensitive to layout and colour. Use it for offline demos
and tests; every output names it ``thumbnail{s}-weight-free``.
"""

from __future__ import annotations

from typing import Any

from ..errors import SplatplanError
from .base import Encoder, torch
from .preprocess import area_resize


class ThumbnailEncoder(Encoder):
    """Normalised ``size x size`` thumbnail, flattened: dim = 3 size^2. No weights, no patch tokens."""

    has_tokens = False

    def __init__(self, size: int = 16, *, device: Any = "cpu", batch_size: int = 256, normalize: bool = False) -> None:
        super().__init__(device=device, batch_size=batch_size, normalize=normalize)
        if not 1 <= int(size) <= 256:
            raise SplatplanError(f"thumbnail size must be between 1 and 256 pixels, got {size}")
        s = int(size)
        self.image_size = (s, s)
        self.dim = 3 * s * s
        self.name = f"thumbnail{s}-weight-free"
        self.description = f"weight-free: {s}x{s} area-averaged thumbnail, per-image mean/std normalised, unit norm (not a learned encoder)"

    def _forward(self, x: "torch.Tensor", tokens: bool):
        t = area_resize(x, self.image_size).permute(0, 2, 3, 1).reshape(x.shape[0], -1)  # (b, s*s*3) row-major HWC
        t = t - t.mean(dim=1, keepdim=True)
        std = t.pow(2).mean(dim=1, keepdim=True).sqrt()
        e = t / (std.clamp_min(1e-6) * self.dim**0.5)
        return torch.where(std > 1e-6, e, torch.zeros_like(e)), None
