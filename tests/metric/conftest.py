"""Shared fixtures for the metric tests: random anisotropic scenes, devices to fan out over."""

from __future__ import annotations

import numpy as np

from splatplan._warp import wp
from splatplan.scenes.splats import Splats

DEVICES = ["cpu"] + (["cuda:0"] if wp().is_cuda_available() else [])


def random_quats(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 4) uniformly random unit wxyz quaternions."""
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def random_scene(rng: np.random.Generator, n: int, *, disks: bool = False, scale: float = 0.004) -> Splats:
    """n anisotropic splats in [-0.3, 0.3]^3 with log-normal stds around ``scale`` (2DGS disks optional)."""
    scales = np.exp(rng.normal(np.log(scale), 0.7, (n, 3)))
    if disks:
        scales[:, 2] = 0.0
    return Splats(
        means=rng.uniform(-0.3, 0.3, (n, 3)),
        quats=random_quats(rng, n),
        scales=scales,
        opacities=rng.uniform(0.2, 1.0, n),
        colors=rng.uniform(0, 1, (n, 3)),
    )
