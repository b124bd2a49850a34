"""Strongly elongated links (axis ratios 2-6, random rotations, splats packed around them) against the float64 brute force."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.metric import MetricConfig
from splatplan.metric.wp_metric import TierConfig
from splatplan.scenes.splats import Splats, quat_to_rotmat

from .conftest import DEVICES, random_quats, random_scene
from .test_kernel_vs_reference import _compare


def _elongated_links(rng: np.random.Generator, b: int) -> tuple[np.ndarray, np.ndarray]:
    """(b, 4) random wxyz rotations, (b, 3) semi-axes with a_max / a_mid in [2, 6], the long axis in a random slot."""
    a_mid = rng.uniform(0.008, 0.02, b)
    ratio = rng.uniform(2.0, 6.0, b)
    axes = np.stack([ratio * a_mid, a_mid, a_mid * rng.uniform(0.4, 1.0, b)], axis=1)  # (b, 3)
    return random_quats(rng, b), rng.permuted(axes, axis=1)


def _packed_scene(rng: np.random.Generator, quats: np.ndarray, axes: np.ndarray, centers: np.ndarray, per_link: int) -> Splats:
    """Splats packed in and just around each link ellipsoid scaled by up to 3.5 (every border region populated)."""
    rot = quat_to_rotmat(quats)  # (b, 3, 3) world <- link
    u = rng.normal(size=(len(centers), per_link, 3))
    u *= (rng.uniform(0.0, 1.0, (len(centers), per_link, 1)) ** (1 / 3) * 3.5) / np.linalg.norm(u, axis=2, keepdims=True)
    means = centers[:, None] + np.einsum("bij,bkj->bki", rot, u * axes[:, None])  # (b, per_link, 3) world
    base = random_scene(rng, means.size // 3, scale=0.003)
    return Splats(means.reshape(-1, 3), base.quats, base.scales, base.opacities, base.colors)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 1.0, 2.0])
@pytest.mark.parametrize("cell_factor", [1.5, 0.3])
def test_elongated_links_match_reference(device, n_sigma, cell_factor):
    rng = np.random.default_rng(int(n_sigma * 10) + int(cell_factor * 100))
    b = 60
    quats, axes = _elongated_links(rng, b)
    centers = rng.uniform(-0.2, 0.2, (b, 3))
    scene = _packed_scene(rng, quats, axes, centers, 40)
    centers = centers + rng.normal(0, 0.003, centers.shape)  # queries near (not on) the packed links
    cfg = MetricConfig(n_sigma=n_sigma, s2_cap=9.0, k_collide=2)
    _compare(scene, centers, quats, axes, cfg, device, TierConfig(cell_factor=cell_factor))


@pytest.mark.parametrize("n_sigma", [0.0, 1.0])
def test_elongated_links_unclipped_collide_kernel(n_sigma):
    """TierConfig(collide_row_clip=False): the collision-only kernel scans whole rows of the link box."""
    rng = np.random.default_rng(77 + int(n_sigma))
    quats, axes = _elongated_links(rng, 60)
    centers = rng.uniform(-0.2, 0.2, (60, 3))
    scene = _packed_scene(rng, quats, axes, centers, 40)
    centers = centers + rng.normal(0, 0.003, centers.shape)
    cfg = MetricConfig(n_sigma=n_sigma, s2_cap=9.0, k_collide=2)
    _compare(scene, centers, quats, axes, cfg, "cpu", TierConfig(cell_factor=0.3, collide_row_clip=False))
