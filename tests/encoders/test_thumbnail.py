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
