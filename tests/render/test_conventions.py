"""Camera conventions, background compositing, outputs types, empty scenes and bad input."""

from __future__ import annotations

import numpy as np
import pytest

import splatplan
from splatplan.errors import SplatplanError
from splatplan.render import Camera, SplatRenderer, intrinsics_from_fov, look_at
from splatplan.scenes.splats import Splats

from .conftest import cameras, random_scene


def _dot(p, color=(1.0, 0.0, 0.0), std=0.004):
    return Splats(np.atleast_2d(p), [[1, 0, 0, 0]], [[std, std, std]], [0.9], [color])


def test_pixel_centres_and_opencv_axes():
    """Identity viewmat: camera at the origin looking along +z, x right, y down; centres at +0.5."""
    k = np.array([[100.0, 0, 32.0], [0, 100.0, 24.0], [0, 0, 1]])
    # x/z = 0.105 -> u = 42.5 (centre of column 42); y/z = -0.085 -> v = 15.5 (row 15, above the centre row)
    res = splatplan.render.render(_dot([0.105, -0.085, 1.0]), np.eye(4), k, 64, 48)
    row, col = np.unravel_index(np.argmax(res.alpha[0]), (48, 64))
    assert (row, col) == (15, 42)
    assert res.alpha[0, 15, 42] == pytest.approx(0.9, abs=1e-6)
    assert res.depth[0, 15, 42] == pytest.approx(1.0, rel=1e-5)
    # symmetric neighbours get equal alpha: the splat sits exactly on the pixel centre
    assert res.alpha[0, 15, 41] == pytest.approx(res.alpha[0, 15, 43], rel=1e-5)


def test_look_at_orientation():
    """From +x looking at the origin with z up: world +z is up in the image, world +y is right."""
    v = look_at([2.0, 0.0, 0.0], [0.0, 0.0, 0.0], up=[0, 0, 1])
    k = intrinsics_from_fov(60, 64, 64)
    up = splatplan.render.render(_dot([0.0, 0.0, 0.4]), v, k, 64, 64).alpha[0]
    right = splatplan.render.render(_dot([0.0, 0.4, 0.0]), v, k, 64, 64).alpha[0]
    r_up, c_up = np.unravel_index(np.argmax(up), up.shape)
    r_rt, c_rt = np.unravel_index(np.argmax(right), right.shape)
    assert r_up < 31 and abs(c_up - 31.5) <= 1
    assert c_rt > 32 and abs(r_rt - 31.5) <= 1
    cam = Camera.look_at([2.0, 0.0, 0.0], [0, 0, 0], fov_deg=60, width=64, height=64)
    np.testing.assert_allclose(cam.position, [2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(cam.viewmat, v)


def test_intrinsics_from_fov():
    k = intrinsics_from_fov(90.0, 200, 100)
    np.testing.assert_allclose(k, [[100.0, 0, 100.0], [0, 100.0, 50.0], [0, 0, 1]])
    kv = intrinsics_from_fov(90.0, 200, 100, axis="vertical")
    assert kv[0, 0] == pytest.approx(50.0)
    with pytest.raises(SplatplanError):
        intrinsics_from_fov(180.0, 10, 10)


def test_background_compositing_and_output_types():
    scene = random_scene(80, seed=2)
    v, k = cameras(24, 20)
    with SplatRenderer(scene, "cpu") as r:
        a = r.render(v, k, 24, 20, background=(0, 0, 0))
        b = r.render(v, k, 24, 20, background=(0.2, 0.5, 1.0))
        np.testing.assert_allclose(b.rgb - a.rgb, (1 - a.alpha)[..., None] * np.array([0.2, 0.5, 1.0]), atol=1e-6)
        assert a.rgb.dtype == np.float32 and a.rgb.shape == (4, 20, 24, 3) and a.depth.shape == (4, 20, 24)
        torch = pytest.importorskip("torch")
        t = r.render(torch.from_numpy(v), torch.from_numpy(k), 24, 20)
        assert isinstance(t.rgb, torch.Tensor) and t.rgb.shape == (4, 20, 24, 3)
        np.testing.assert_array_equal(t.rgb.numpy(), a.rgb)


def test_empty_scene_renders_background():
    empty = Splats(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    v, k = cameras(20, 18)
    res = splatplan.render.render(empty, v, k, 20, 18, background=(0.25, 0.5, 0.75))
    np.testing.assert_array_equal(res.rgb, np.broadcast_to(np.float32([0.25, 0.5, 0.75]), (4, 18, 20, 3)))
    assert not res.alpha.any() and not res.depth.any()


def test_splats_behind_the_camera_are_invisible():
    scene = _dot([0.0, 0.0, -1.0], std=0.5)
    res = splatplan.render.render(scene, np.eye(4), intrinsics_from_fov(60, 16, 16), 16, 16)
    assert not res.alpha.any()


@pytest.mark.parametrize(
    "viewmat, K, size, match",
    [
        (np.full((4, 4), np.nan), None, (8, 8), "NaN"),
        (np.diag([1.0, 1.0, 0.0, 1.0]), None, (8, 8), "singular or not a rigid"),
        (np.diag([2.0, 2.0, 2.0, 1.0]), None, (8, 8), "not a rigid"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), None, (8, 8), "not a rigid"),  # a reflection
        (np.eye(4), np.zeros((3, 3)), (8, 8), "singular"),
        (np.eye(4), np.array([[10.0, 1.0, 4], [0, 10, 4], [0, 0, 1]]), (8, 8), "skew"),
        (np.eye(4), np.full((3, 3), np.inf), (8, 8), "NaN or Inf"),
        (np.eye(4)[:3], None, (8, 8), "shape"),
        (np.eye(4), None, (0, 8), "width must be >= 1"),
        (np.eye(4), None, (8, -3), "height must be >= 1"),
        (np.eye(4), None, (100000, 8), "exceeds"),
        (np.stack([np.eye(4)] * 2000), None, (1024, 1024), "GiB"),
    ],
)
def test_bad_input_is_a_one_line_error(viewmat, K, size, match):
    k = np.array([[10.0, 0, 4], [0, 10, 4], [0, 0, 1]]) if K is None else K
    with pytest.raises(SplatplanError, match=match) as exc:
        splatplan.render.render(random_scene(5), viewmat, k, *size)
    assert "\n" not in str(exc.value)


def test_bad_options():
    scene = random_scene(5)
    k = intrinsics_from_fov(60, 8, 8)
    for kw, match in (({"near": 0.0}, "near"), ({"far": 0.001}, "far"), ({"background": (1, 2)}, "background"),
                      ({"sh_degree": 4}, "sh_degree"), ({"backend": "opengl"}, "backend"), ({"device": "tpu"}, "device")):  # fmt: skip
        with pytest.raises(SplatplanError, match=match):
            splatplan.render.render(scene, np.eye(4), k, 8, 8, **kw)
    with pytest.raises(SplatplanError, match="Ks"):
        splatplan.render.render(scene, np.stack([np.eye(4)] * 3), np.stack([k] * 2), 8, 8)


def test_reference_backend_through_the_api():
    scene = random_scene(40, sh_degree=1, seed=9)
    v, k = cameras(16, 12)
    a = splatplan.render.render(scene, v, k, 16, 12, backend="reference")
    b = splatplan.render.render(scene, v, k, 16, 12, device="cpu")
    assert np.abs(a.rgb - b.rgb).max() < 1e-3


def test_render_function_is_reachable_however_the_package_was_imported():
    """``splatplan.render`` is the package (not callable); the function is ``splatplan.render.render``."""
    import splatplan.render.cameras  # noqa: F401  (binds the package to splatplan.render)
    from splatplan.render.api import render

    assert not callable(splatplan.render) and splatplan.render.render is render
    res = splatplan.render.render(_dot([0.0, 0.0, 1.0]), np.eye(4), intrinsics_from_fov(60, 8, 8), 8, 8)
    assert res.alpha.max() > 0.2  # the dot sits on a pixel corner (cx = 4)
    assert splatplan.RenderResult is splatplan.render.RenderResult and splatplan.Camera is Camera
