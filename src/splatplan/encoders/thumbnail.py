"""A weight-free encoder: the normalised low-resolution image itself (not a learned feature).

Single scale (``levels = 1``): e = flatten(T) standardised per image over all its values, divided
by sqrt(D), where T is the (s, s, 3) area-averaged thumbnail, so ||e|| = 1 (0 for a constant image)
and ``||e_t - e_r||^2 = 2 (1 - corr(T_t, T_r))``: invariant to brightness offset and contrast gain
(I -> a I + b, a > 0, before clamping), sensitive to layout and colour.

Multi-scale (``levels = L > 1``): a Laplacian pyramid of thumbnails. With G_k the area-averaged
thumbnail of side s_k = s / 2^(L-1-k) (k = 0 coarsest), the bands are G_0 and
``B_k = G_k - up(G_(k-1))`` (bilinear upsampling), each standardised and scaled to unit norm as
above, concatenated and divided by sqrt(L) (so ||e|| = 1 again and the cost is the mean of the
bands' 2 (1 - corr)). The coarse band gives a wide basin; the band-pass ones respond to the edge and
texture detail that single thumbnails average away (views a few centimetres apart that differ only
by a slight perspective change and a shift of fine texture).

Use it for offline demos and tests; every output names it ``thumbnail{s}-weight-free`` (single
scale) or ``thumbnail{s}-pyramid{L}-weight-free``.
"""

from __future__ import annotations

from typing import Any

from ..errors import SplatplanError
from .base import Encoder, torch
from .preprocess import area_resize


def _unit(t: "torch.Tensor") -> "torch.Tensor":
    """(b, ...) -> (b, D): flattened, mean-removed, unit norm (0 for a constant row)."""
    t = t.reshape(t.shape[0], -1)
    t = t - t.mean(dim=1, keepdim=True)
    std = t.pow(2).mean(dim=1, keepdim=True).sqrt()
    e = t / (std.clamp_min(1e-6) * t.shape[1] ** 0.5)
    return torch.where(std > 1e-6, e, torch.zeros_like(e))


class ThumbnailEncoder(Encoder):
    """Normalised ``size x size`` thumbnail (or a ``levels``-band Laplacian pyramid of them),
    flattened. No weights, no patch tokens."""

    has_tokens = False

    def __init__(self, size: int = 16, *, levels: int = 1, device: Any = "auto", batch_size: int = 256, normalize: bool = False) -> None:
        super().__init__(device=device, batch_size=batch_size, normalize=normalize)
        if not 1 <= int(size) <= 256:
            raise SplatplanError(f"thumbnail size must be between 1 and 256 pixels, got {size}")
        s, n = int(size), int(levels)
        if n < 1 or s % (2 ** (n - 1)):
            raise SplatplanError(f"thumbnail pyramid: levels must be >= 1 and size ({s}) divisible by 2^(levels - 1) = {2 ** max(n - 1, 0)}, got levels={levels}")
        self.image_size = (s, s)
        self.levels = n
        self.sizes = tuple(s // 2 ** (n - 1 - k) for k in range(n))  # coarse -> fine
        self.dim = 3 * sum(v * v for v in self.sizes)
        if n == 1:
            self.name = f"thumbnail{s}-weight-free"
            self.description = f"weight-free: {s}x{s} area-averaged thumbnail, per-image mean/std normalised, unit norm (not a learned encoder)"
        else:
            self.name = f"thumbnail{s}-pyramid{n}-weight-free"
            self.description = (f"weight-free: Laplacian pyramid of area-averaged thumbnails {'/'.join(map(str, self.sizes))}, "
                                "each band mean/std normalised, unit norm overall (not a learned encoder)")  # fmt: skip

    def _forward(self, x: "torch.Tensor", tokens: bool):
        hwc = lambda t: t.permute(0, 2, 3, 1)  # noqa: E731  row-major HWC like the single-scale layout
        if self.levels == 1:
            return _unit(hwc(area_resize(x, self.image_size))), None
        gs = [area_resize(x, (v, v)) for v in self.sizes]  # (b, 3, s_k, s_k) coarse -> fine
        bands = [gs[0]] + [g - torch.nn.functional.interpolate(lo, size=g.shape[-2:], mode="bilinear", align_corners=False) for lo, g in zip(gs[:-1], gs[1:])]
        return torch.cat([_unit(hwc(b)) for b in bands], dim=1) / self.levels**0.5, None
