"""Image preprocessing in torch (torchvision has no working CPU build here).

All functions take (B, 3, H, W) float32 RGB in [0, 1] and keep the device.
"""

from __future__ import annotations

from .base import torch

F = torch.nn.functional

#: ImageNet channel statistics (RGB), used by DINOv2.
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def resize(x: "torch.Tensor", size: tuple[int, int]) -> "torch.Tensor":
    """(B, 3, H, W) -> (B, 3, h, w): bilinear with antialiasing when shrinking (no crop, aspect not kept)."""
    if tuple(x.shape[-2:]) == tuple(size):
        return x
    return F.interpolate(x, size=tuple(size), mode="bilinear", align_corners=False, antialias=True)


def area_resize(x: "torch.Tensor", size: tuple[int, int]) -> "torch.Tensor":
    """(B, 3, H, W) -> (B, 3, h, w): mean over each output cell (exact box filter for integer factors)."""
    if tuple(x.shape[-2:]) == tuple(size):
        return x
    return F.adaptive_avg_pool2d(x, (size[0], size[1]))


def imagenet_normalize(x: "torch.Tensor") -> "torch.Tensor":
    """(x - mean) / std per channel with the ImageNet statistics."""
    mean = x.new_tensor(IMAGENET_MEAN).view(1, 3, 1, 1)
    std = x.new_tensor(IMAGENET_STD).view(1, 3, 1, 1)
    return (x - mean) / std
