"""The Warp rasteriser (both blending kernels) against the float64 per-pixel numpy reference."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.render import SplatRenderer, look_at
from splatplan.render.reference import render_reference

from .conftest import DEVICES, VIEWS, cameras, psnr, random_scene, with_near_splats

W, H = 40, 28  # not multiples of the tile size: partial tiles on both axes


def _check(got, want, what: str) -> None:
    for b in range(len(want)):
        p = psnr(got.rgb[b], want.rgb[b])
        assert p >= 40.0, f"{what} camera {b}: PSNR {p:.1f} dB"
        da = np.abs(got.alpha[b] - want.alpha[b]).max()
        assert da <= 1e-3, f"{what} camera {b}: alpha differs by {da:.2e}"
        sure = (want.alpha[b] > 0.05) & (np.abs(got.alpha[b] - want.alpha[b]) < 1e-4)
        np.testing.assert_allclose(got.depth[b][sure], want.depth[b][sure], rtol=2e-3, atol=2e-3, err_msg=f"{what} camera {b} depth")
        assert np.all(got.depth[b][want.alpha[b] == 0] == 0)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("sh_degree", [0, 1, 2, 3])
def test_kernels_match_reference(device, sh_degree):
    scene = random_scene(160, sh_degree=sh_degree, seed=sh_degree)
    scene = with_near_splats(scene, VIEWS[2][0], VIEWS[2][1])
    v, k = cameras(W, H)
    want = render_reference(scene, v, k, W, H, background=(0.1, 0.2, 0.3))
    assert want.alpha.max() > 0.5 and want.alpha.min() < 0.5  # the views see something, not everything
    for blend in ("tile", "pixel"):
        with SplatRenderer(scene, device, blend=blend) as r:
            got = r.render(v, k, W, H, background=(0.1, 0.2, 0.3))
        _check(got, want, f"{device}/{blend}/deg{sh_degree}")


@pytest.mark.parametrize("device", DEVICES)
def test_sh_degree_truncation_and_near_far(device):
    scene = random_scene(120, sh_degree=3, seed=7)
    v, k = cameras(32, 32)
    with SplatRenderer(scene, device) as r:
        for deg in (0, 2):
            _check(r.render(v, k, 32, 32, sh_degree=deg), render_reference(scene, v, k, 32, 32, sh_degree=deg), f"deg{deg}")
        got = r.render(v, k, 32, 32, near=1.5, far=3.2)
    _check(got, render_reference(scene, v, k, 32, 32, near=1.5, far=3.2), "near/far")


def test_disks_only_scene_and_large_image():
    """2DGS disks everywhere (edge-on ones included) at a size with many tiles."""
    scene = random_scene(150, disks=1.0, seed=3)
    assert scene.is_2d
    v, k = cameras(70, 50, fov=50.0)
    got = SplatRenderer(scene, "cpu").render(v[:2], k, 70, 50)
    _check(got, render_reference(scene, v[:2], k, 70, 50), "disks")


def test_threads_and_chunks_do_not_change_the_images():
    scene = random_scene(100, sh_degree=1, seed=5)
    eyes = np.array([[3.0 * np.cos(a), 3.0 * np.sin(a), 0.5] for a in np.linspace(0, 6, 7)])
    v = look_at(eyes, np.zeros(3))
    k = np.array([[30.0, 0, 16], [0, 30.0, 12], [0, 0, 1]])
    one = SplatRenderer(scene, "cpu", threads=1)
    many = SplatRenderer(scene, "cpu", threads=3)
    a = one.render(v, k, 32, 24)
    b = many.render(v, k, 32, 24)
    c = many.render(v, k, 32, 24)  # reused workspaces
    singles = [one.render(v[i], k, 32, 24) for i in range(len(v))]
    many.close()
    for x in (b, c):
        np.testing.assert_array_equal(a.rgb, x.rgb)
        np.testing.assert_array_equal(a.alpha, x.alpha)
    np.testing.assert_array_equal(a.depth, np.concatenate([s.depth for s in singles]))


def test_chunks_split_when_the_workspace_cap_is_reached():
    """Big splats touch every tile: a chunk whose pairs exceed the cap is split, results unchanged."""
    from splatplan.render import renderer as rmod

    scene = random_scene(40, seed=8)
    scene.scales[:] = 0.6  # every splat covers most tiles of every view
    v, k = cameras(64, 64)
    ref = SplatRenderer(scene, "cpu", threads=1)
    want = ref.render(v, k, 64, 64)
    fixed = 4 * 64 * 64 * 20 + ref._scene_bytes  # outputs + scene
    one_cam = 40 * 16 * rmod._PAIR_BYTES + 40 * rmod._ROW_BYTES  # at most 16 tiles per splat
    r = SplatRenderer(scene, "cpu", threads=1, max_bytes=fixed + one_cam + 1000)
    r._chunk_size = lambda b, *a: b  # force one chunk of all 4 cameras: too big, must split
    got = r.render(v, k, 64, 64)
    np.testing.assert_array_equal(got.rgb, want.rgb)
    np.testing.assert_array_equal(got.alpha, want.alpha)
    tight = SplatRenderer(scene, "cpu", threads=1, max_bytes=fixed + 2000)
    with pytest.raises(SplatplanError, match="workspace"):
        tight.render(v, k, 64, 64)


def test_splats_just_off_the_image_that_reach_into_it():
    """Splats whose centres project just outside the image (0-12 px beyond every edge), elongated and
    flat ones among them, footprints of 1-20 px: the project kernel's early cull (a bound on the
    footprint before the 2D covariance) must keep every one that reaches a pixel."""
    from splatplan.render import intrinsics_from_fov
    from splatplan.scenes.splats import Splats

    rng = np.random.default_rng(11)
    v = look_at(np.array([-3.0, 0.2, 0.4]), np.zeros(3))[None]  # (1, 4, 4) world -> camera
    k = intrinsics_from_fov(70.0, W, H)
    n = 240
    edge = rng.integers(0, 4, n)  # left, right, top, bottom
    off = rng.uniform(0.0, 12.0, n)  # pixels beyond the edge
    along = rng.uniform(0.0, 1.0, n)
    u = np.where(edge == 0, -off, np.where(edge == 1, W + off, along * W))
    vv = np.where(edge == 2, -off, np.where(edge == 3, H + off, along * H))
    z = rng.uniform(1.5, 4.5, n)  # view depth
    cam_pts = np.column_stack([(u - k[0, 2]) / k[0, 0] * z, (vv - k[1, 2]) / k[1, 1] * z, z])  # camera frame
    rot, t = v[0, :3, :3], v[0, :3, 3]
    means = (cam_pts - t) @ rot  # world frame: R^T (x - t)
    scales = np.exp(rng.uniform(np.log(0.002), np.log(0.15), (n, 3)))
    scales[: n // 4, 2] = 0.0  # disks
    scales[n // 4 : n // 2, 0] *= 8.0  # needles
    scene = Splats(means, rng.normal(size=(n, 4)), scales, rng.uniform(0.05, 1.0, n), rng.uniform(0, 1, (n, 3)))
    loose = v.copy()
    loose[0, :3, :3] *= 1.0 + 4e-4  # a rotation part off by 8e-4 (within the camera check's 1e-3)
    for vm, name in ((v, "rigid"), (loose, "loose")):
        want = render_reference(scene, vm, k, W, H, background=(0.1, 0.2, 0.3))
        assert 0.02 < (want.alpha[0] > 0.01).mean() < 0.9  # splats from outside reach in, not everywhere
        for blend in ("tile", "pixel"):
            got = SplatRenderer(scene, "cpu", blend=blend, threads=1).render(vm, k, W, H, background=(0.1, 0.2, 0.3))
            _check(got, want, f"off-image/{name}/{blend}")
