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


#: MetricConfig regimes the collision-only shortcuts must not change: n_sigma 0 / 1 / 3 (the paper's
#: squared linearisation, no opacity rule), an opacity threshold, and k_collide 2
COLLIDE_REGIMES = [
    dict(n_sigma=0.0),
    dict(n_sigma=1.0),
    dict(n_sigma=3.0, linearize="squared", opacity_min=0.0, opacity_scaled_inflation=False),
    dict(n_sigma=1.0, opacity_min=0.4),
    dict(n_sigma=0.0, k_collide=2),
]


def plane_walls(rng: np.random.Generator, n: int, *, scale: float, noise: float) -> Splats:
    """n splats (stds around ``scale``) on three planes, two axis-aligned walls and a tilted one,
    ``noise`` off them."""
    uv = rng.uniform(-0.3, 0.3, (n, 2))
    k = rng.integers(0, 3, n)
    p = np.zeros((n, 3))
    p[k == 0] = np.column_stack([np.full((k == 0).sum(), 0.1), uv[k == 0]])
    p[k == 1] = np.column_stack([uv[k == 1, 0], np.full((k == 1).sum(), -0.15), uv[k == 1, 1]])
    t = uv[k == 2]
    p[k == 2] = np.column_stack([t[:, 0], t[:, 1], 0.5 * t[:, 0] + 0.3 * t[:, 1] - 0.1])
    scene = random_scene(rng, n, scale=scale)
    scene.means[:] = p + rng.normal(scale=noise, size=p.shape)
    return scene


def option_pair(scene: Splats, device: str, option: str, **cfg):
    """Two checkers of ``scene`` with the MetricConfig ``cfg``, the TierConfig flag ``option`` on and
    off (a 2^18-voxel mean-distance grid)."""
    from splatplan.metric import CollisionChecker, MetricConfig
    from splatplan.metric.tiers import TierConfig

    conf = MetricConfig(**cfg)
    return tuple(CollisionChecker(scene, config=conf, device=device, tiers=TierConfig(**{option: flag}, distance_grid_voxels=2**18)) for flag in (True, False))


def near_surface_links(rng: np.random.Generator, scene: Splats, n: int):
    """n random links: half within ~4 cm of the scene's means (rods, 4x longer on one axis), half
    uniform in [-0.6, 0.6]^3. Returns centres (n, 3), wxyz quaternions (n, 4), semi-axes (n, 3)."""
    near = np.asarray(scene.means)[rng.integers(0, len(scene.means), n // 2)] + rng.normal(scale=0.04, size=(n // 2, 3))
    centers = np.concatenate([near, rng.uniform(-0.6, 0.6, (n - n // 2, 3))])
    quats = random_quats(rng, n)
    axes = rng.uniform(0.004, 0.03, (n, 3))
    axes[: n // 2, 0] *= 4  # rods
    return centers, quats, axes
