"""The weight-free thumbnail encoder: against a numpy reference, and its invariances."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splatplan.encoders import load_encoder


def thumbnail_reference(img: np.ndarray, s: int) -> np.ndarray:
    """Slow numpy reference for an (H, W, 3) image whose sides are multiples of s."""
    h, w, _ = img.shape
    t = img.reshape(s, h // s, s, w // s, 3).mean(axis=(1, 3)).reshape(-1).astype(np.float64)  # (s*s*3,) row-major HWC
    t = t - t.mean()
    std = np.sqrt((t**2).mean())
    return t / (std * np.sqrt(t.size)) if std > 1e-6 else np.zeros_like(t)


@pytest.fixture(scope="module")
def thumb():
    return load_encoder("thumbnail", image_size=8)


def test_matches_reference(thumb, images):
    x = images[:, :40, :40]  # 40 = 5 * 8
    want = np.stack([thumbnail_reference(im, 8) for im in x])
    np.testing.assert_allclose(thumb.encode(x), want, atol=1e-5)
    assert thumb.dim == 8 * 8 * 3 and thumb.name == "thumbnail8-weight-free"


def test_unit_norm_and_constant_image(thumb, images):
    np.testing.assert_allclose(np.linalg.norm(thumb.encode(images), axis=1), 1.0, rtol=1e-5)
    assert np.all(thumb.encode(np.full((2, 16, 16, 3), 0.3, np.float32)) == 0)


@settings(max_examples=20, deadline=None)
@given(gain=st.floats(0.2, 1.0), offset=st.floats(0.0, 0.4))
def test_invariant_to_brightness_and_contrast(gain, offset):
    enc = load_encoder("thumbnail", image_size=8)
    rng = np.random.default_rng(3)
    img = (rng.random((1, 24, 24, 3)) * 0.5 + 0.1).astype(np.float32)
    other = np.clip(gain * img + offset, 0, 1)  # stays inside [0, 1]: 1.0 * 0.6 + 0.4 = 1
    e0, e1 = enc.encode(img), enc.encode(other)
    assert enc.image_cost(e0[0], e1)[0] < 1e-8


def test_cost_is_two_minus_two_correlation(thumb, images):
    e = thumb.encode(images)
    t = [thumbnail_reference(im, 8) for im in images[:, :40, :40]]
    corr = np.corrcoef(t[0], t[1])[0, 1]
    e40 = thumb.encode(images[:2, :40, :40])
    np.testing.assert_allclose(thumb.image_cost(e40[0], e40[1:])[0], 2 - 2 * corr, atol=1e-5)
    assert e.shape == (4, 192)


def test_sensitive_to_layout_and_colour(thumb, images):
    x = images[:1]
    flipped = x[:, :, ::-1]
    swapped = x[..., ::-1]
    e = thumb.encode(np.concatenate([x, flipped, swapped]))
    c = thumb.image_cost(e[0], e)
    assert c[0] == 0 and c[1] > 0.01 and c[2] > 0.01


def pyramid_reference(img: np.ndarray, s: int, levels: int) -> np.ndarray:
    """Slow numpy reference of the Laplacian thumbnail pyramid (bilinear upsampling, half-pixel centres)."""

    def up(a: np.ndarray, n: int) -> np.ndarray:  # (m, m, 3) -> (n, n, 3), align_corners=False
        m = a.shape[0]
        x = np.clip((np.arange(n) + 0.5) * m / n - 0.5, 0, m - 1)
        i0 = np.floor(x).astype(int)
        i1 = np.minimum(i0 + 1, m - 1)
        f = x - i0
        rows = a[i0] * (1 - f)[:, None, None] + a[i1] * f[:, None, None]
        return rows[:, i0] * (1 - f)[None, :, None] + rows[:, i1] * f[None, :, None]

    def unit(t: np.ndarray) -> np.ndarray:
        t = t.reshape(-1) - t.mean()
        std = np.sqrt((t**2).mean())
        return t / (std * np.sqrt(t.size)) if std > 1e-6 else np.zeros_like(t)

    h = img.shape[0]
    sizes = [s // 2 ** (levels - 1 - k) for k in range(levels)]
    gs = [img.reshape(v, h // v, v, h // v, 3).mean(axis=(1, 3)).astype(np.float64) for v in sizes]
    bands = [gs[0]] + [g - up(lo, g.shape[0]) for lo, g in zip(gs[:-1], gs[1:])]
    return np.concatenate([unit(b) for b in bands]) / np.sqrt(levels)


@pytest.mark.parametrize("levels", [2, 3])
def test_pyramid_matches_reference(images, levels):
    from splatplan.encoders.thumbnail import ThumbnailEncoder

    enc = ThumbnailEncoder(16, levels=levels)
    x = images[:, :32, :32]
    want = np.stack([pyramid_reference(im, 16, levels) for im in x])
    got = enc.encode(x)
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert got.shape == (len(x), enc.dim) and enc.name == f"thumbnail16-pyramid{levels}-weight-free"
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, rtol=1e-5)
    # brightness / contrast invariance holds band by band
    np.testing.assert_allclose(enc.encode(np.clip(0.5 * x + 0.2, 0, 1)), got, atol=1e-5)


def test_pyramid_bad_levels():
    from splatplan.encoders.thumbnail import ThumbnailEncoder
    from splatplan.errors import SplatplanError

    with pytest.raises(SplatplanError, match="divisible"):
        ThumbnailEncoder(12, levels=4)
    with pytest.raises(SplatplanError, match="levels"):
        ThumbnailEncoder(16, levels=0)
