"""Invariants of the renderer (hypothesis): rigid motions of scene + camera, splat order, opacity 0."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from splatplan.render import SplatRenderer, look_at
from splatplan.scenes.splats import Splats, quat_multiply, rotmat_to_quat

from .conftest import psnr, random_scene

K = np.array([[30.0, 0, 16], [0, 30.0, 12], [0, 0, 1]])
V = look_at(np.array([[2.5, 0.3, 0.8], [-0.2, 2.4, -0.5]]), np.zeros(3))


def _rot(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_rigid_motion_of_scene_and_cameras_leaves_images_unchanged(seed):
    rng = np.random.default_rng(seed)
    scene = random_scene(60, seed=seed)  # SH degree 0 (higher bands would need rotated coefficients)
    r, t = _rot(rng), rng.normal(size=3)
    g = np.eye(4)
    g[:3, :3], g[:3, 3] = r, t  # world' <- world
    moved = Splats(scene.means @ r.T + t, quat_multiply(rotmat_to_quat(r), scene.quats), scene.scales, scene.opacities, scene.colors)
    v2 = V @ np.linalg.inv(g)  # camera <- world'
    a = SplatRenderer(scene, "cpu").render(V, K, 32, 24)
    b = SplatRenderer(moved, "cpu").render(v2, K, 32, 24)
    for i in range(len(V)):
        assert psnr(a.rgb[i], b.rgb[i]) > 60
        assert np.abs(a.alpha[i] - b.alpha[i]).max() < 1e-3


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_splat_order_and_invisible_splats_do_not_matter(seed):
    rng = np.random.default_rng(seed)
    scene = random_scene(50, sh_degree=2, seed=seed)
    perm = rng.permutation(len(scene))
    extra = random_scene(20, sh_degree=2, seed=seed + 1)
    extra.opacities[:] = 0.0  # transparent splats add nothing
    both = Splats(
        np.concatenate([scene.means[perm], extra.means]), np.concatenate([scene.quats[perm], extra.quats]),
        np.concatenate([scene.scales[perm], extra.scales]), np.concatenate([scene.opacities[perm], extra.opacities]),
        np.concatenate([scene.colors[perm], extra.colors]), np.concatenate([scene.sh_rest[perm], extra.sh_rest]),
    )  # fmt: skip
    a = SplatRenderer(scene, "cpu").render(V, K, 32, 24)
    b = SplatRenderer(both, "cpu").render(V, K, 32, 24)
    np.testing.assert_allclose(a.rgb, b.rgb, atol=1e-5)
    np.testing.assert_allclose(a.alpha, b.alpha, atol=1e-6)
