"""Shared fixtures of the baseline tests: small random anisotropic scenes, 2 torch threads."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

torch.set_num_threads(2)


def random_scene(n: int, seed: int, smin: float = 0.005, smax: float = 0.1, spread: float = 0.1) -> dict[str, np.ndarray]:
    """n random anisotropic, randomly rotated splats (float64 arrays; wxyz quats; linear scales).

    Also returns ``rot`` (n, 3, 3), built by scipy independently of the code under test.
    """
    rng = np.random.default_rng(seed)
    rot = Rotation.random(n, random_state=seed)
    xyzw = rot.as_quat()
    return {
        "means": rng.normal(size=(n, 3)) * spread,
        "quats": np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1),  # wxyz
        "scales": np.exp(rng.uniform(np.log(smin), np.log(smax), (n, 3))),
        "opacities": rng.uniform(0.05, 1.0, n),
        "rot": rot.as_matrix(),
    }


@pytest.fixture
def make_scene():
    return random_scene
