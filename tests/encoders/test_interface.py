"""The one Encoder interface: shapes, kinds (numpy/torch), image_cost, EmbeddingDistance, bad input, no global state."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from splatplan.encoders import EmbeddingDistance, image_cost, load_encoder
from splatplan.errors import SplatplanError

from .conftest import needs_effnet_weights

ENCODERS = {
    "thumbnail": dict(),
    "dinov2-tiny": dict(random_init=True, image_size=28),
    "efficientnet-lite0": dict(image_size=64),
}


@pytest.fixture(scope="module", params=sorted(ENCODERS))
def enc(request):
    if request.param.startswith("efficientnet"):
        needs_effnet_weights()
    return load_encoder(request.param, **ENCODERS[request.param])


def test_shapes_and_kinds(enc, images):
    e = enc.encode(images)
    assert isinstance(e, np.ndarray) and e.dtype == np.float32 and e.shape == (4, enc.dim)
    assert np.isfinite(e).all()
    t = enc.encode(torch.from_numpy(images))
    assert torch.is_tensor(t) and t.shape == (4, enc.dim) and t.device == torch.device("cpu")
    np.testing.assert_allclose(t.numpy(), e, rtol=1e-5, atol=1e-5)
    q = (images * 255).round().astype(np.uint8)
    np.testing.assert_allclose(enc.encode(q), enc.encode(q.astype(np.float32) / 255), rtol=1e-5, atol=1e-5)
    assert enc.encode(images[:0]).shape == (0, enc.dim)
    if enc.has_tokens:
        tok = enc.encode_tokens(images)
        assert tok.ndim == 3 and tok.shape[0] == 4 and tok.shape[1] == enc.n_tokens and tok.shape[2] == enc.token_dim
    else:
        with pytest.raises(SplatplanError, match="no patch tokens"):
            enc.encode_tokens(images)


def test_batching_does_not_change_results(enc, images):
    ref = enc.encode(images)
    old = enc.batch_size
    enc.batch_size = 1
    try:
        np.testing.assert_allclose(enc.encode(images), ref, rtol=1e-4, atol=1e-4)
    finally:
        enc.batch_size = old


def test_names_are_honest(enc):
    if enc.name.startswith("thumbnail"):
        assert "weight-free" in enc.name and "not a learned" in enc.description
    if enc.name.startswith("dinov2"):
        assert enc.name.endswith("RANDOM-WEIGHTS")
    if enc.name.startswith("efficientnet"):
        assert enc.name == "efficientnet-lite0-imagenet"


def test_image_cost_matches_numpy():
    rng = np.random.default_rng(1)
    t, r = rng.normal(size=8).astype(np.float32), rng.normal(size=(5, 8)).astype(np.float32)
    ref = ((t[None] - r) ** 2).sum(1)
    np.testing.assert_allclose(image_cost(t, r), ref, rtol=1e-6)
    np.testing.assert_allclose(image_cost(t[None], r), ref, rtol=1e-6)
    tb = rng.normal(size=(5, 8)).astype(np.float32)
    np.testing.assert_allclose(image_cost(tb, r), ((tb - r) ** 2).sum(1), rtol=1e-6)
    out = image_cost(torch.from_numpy(t), torch.from_numpy(r))
    assert torch.is_tensor(out) and out.shape == (5,)
    np.testing.assert_allclose(out.numpy(), ref, rtol=1e-6)
    assert image_cost(r, r).max() == 0
    for bad_t, bad_r in [(t[:4], r), (rng.normal(size=(3, 8)), r), (t, r[0])]:
        with pytest.raises(SplatplanError):
            image_cost(bad_t, bad_r)


def test_combined_cost_is_the_formula(tiny_dinov2, images):
    target, rendered = images[0], images[1:]
    g_t, tok_t = tiny_dinov2.features(target[None], tokens=True)
    g_r, tok_r = tiny_dinov2.features(rendered, tokens=True)
    want = 0.7 * ((g_t - g_r) ** 2).sum(1) + 0.3 * ((tok_t - tok_r) ** 2).sum(2).mean(1)
    got = EmbeddingDistance(tiny_dinov2, target, w_global=0.7, w_patch=0.3)(rendered)
    np.testing.assert_allclose(got, want, rtol=1e-4)
    # global only == image_cost; a render equal to the target costs ~0
    np.testing.assert_allclose(EmbeddingDistance(tiny_dinov2, target)(rendered), image_cost(g_t[0], g_r), rtol=1e-5)
    assert EmbeddingDistance(tiny_dinov2, target, 1.0, 1.0)(target[None])[0] < 1e-6
    # one target per rendered image
    per_row = EmbeddingDistance(tiny_dinov2, images[:3], w_patch=1.0)(images[1:])
    assert per_row.shape == (3,) and per_row[0] > 0


def test_combined_cost_bad_input(images):
    thumb = load_encoder("thumbnail")
    with pytest.raises(SplatplanError, match="no patch tokens"):
        EmbeddingDistance(thumb, images[0], w_patch=1.0)
    with pytest.raises(SplatplanError, match="weights"):
        EmbeddingDistance(thumb, images[0], w_global=0.0, w_patch=0.0)
    with pytest.raises(SplatplanError, match="target images"):
        EmbeddingDistance(thumb, images[:2])(images[:3])


def test_gradients_flow_to_torch_images(tiny_dinov2, images):
    for enc in (load_encoder("thumbnail"), tiny_dinov2):
        x = torch.from_numpy(images[1:3].copy()).requires_grad_(True)
        cost = EmbeddingDistance(enc, images[0])(x)
        cost.sum().backward()
        assert x.grad is not None and torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0
    assert torch.is_grad_enabled()  # grad mode restored after encoding
    assert not load_encoder("thumbnail").encode(torch.from_numpy(images)).requires_grad


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((8, 8, 3), np.float32), r"\(B, H, W, 3\).*images\[None\]"),
        (np.zeros((1, 8, 8, 4), np.float32), "3 RGB channels.*alpha"),
        (np.zeros((1, 8, 8, 1), np.float32), "3 RGB channels"),
        (np.full((1, 8, 8, 3), np.nan, np.float32), "NaN"),
        (np.zeros((1, 8, 8, 3), np.int32), "dtype"),
        (np.zeros((1, 0, 8, 3), np.float32), ">= 1"),
        ([[1, 2], [3]], "cannot read"),
    ],
)
def test_bad_images(bad, match):
    with pytest.raises(SplatplanError, match=match):
        load_encoder("thumbnail").encode(bad)


def test_values_outside_unit_range_are_clamped(images):
    enc = load_encoder("thumbnail")
    x = images.copy()
    x[0, :5] = 3.0
    np.testing.assert_allclose(enc.encode(x), enc.encode(np.clip(x, 0, 1)), atol=1e-6)


def test_load_encoder_errors():
    with pytest.raises(SplatplanError, match="unknown encoder"):
        load_encoder("resnet50")
    with pytest.raises(SplatplanError, match="weight-free"):
        load_encoder("thumbnail", weights="/tmp")
    with pytest.raises(SplatplanError, match="pooling"):
        load_encoder("dinov2-tiny", random_init=True, pooling="max")
    with pytest.raises(SplatplanError, match="multiple of the 14"):
        load_encoder("dinov2-tiny", random_init=True, image_size=30)
    with pytest.raises(SplatplanError, match="batch_size"):
        load_encoder("thumbnail", batch_size=0)
    with pytest.raises(SplatplanError, match="device"):
        load_encoder("thumbnail", device="tpu")
    with pytest.raises(SplatplanError, match="load_encoder"):
        load_encoder("thumbnail", colour="blue")


def test_no_hidden_global_state():
    threads = torch.get_num_threads()
    torch.manual_seed(123)
    before = torch.rand(3)
    torch.manual_seed(123)
    a = load_encoder("dinov2-tiny", random_init=True, image_size=28)
    after = torch.rand(3)
    b = load_encoder("dinov2-tiny", random_init=True, image_size=28)
    assert torch.equal(before, after)  # random init does not consume the global RNG
    assert torch.get_num_threads() == threads
    x = np.random.default_rng(0).random((2, 28, 28, 3)).astype(np.float32)
    np.testing.assert_array_equal(a.encode(x), b.encode(x))  # seeded: the same random model each time


def test_normalize_option(images):
    enc = load_encoder("dinov2-tiny", random_init=True, image_size=28, normalize=True, pooling="cls_mean")
    e = enc.encode(images)
    assert e.shape == (4, 2 * 48)
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(enc.encode_tokens(images), axis=2), 1.0, rtol=1e-5)


def test_top_level_api():
    import splatplan

    assert splatplan.load_encoder("thumbnail").name == "thumbnail16-weight-free"


DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", DEVICES)
def test_devices_keep_data_where_it_is(device, images):
    enc = load_encoder("dinov2-tiny", random_init=True, image_size=28, device=device)
    ref = load_encoder("dinov2-tiny", random_init=True, image_size=28).encode(images)
    x = torch.from_numpy(images).to(device)
    e = enc.encode(x)
    assert torch.is_tensor(e) and e.device.type == device
    cost = EmbeddingDistance(enc, x[0], w_patch=1.0)(x)
    assert cost.device.type == device and cost.shape == (4,)
    np.testing.assert_allclose(enc.encode(images), ref, rtol=1e-3, atol=1e-3)  # numpy in -> numpy out, same values


def test_old_encoder_image_cost_name_warns_and_still_works():
    """``splatplan.encoders.ImageCost`` is the deprecated name of :class:`EmbeddingDistance` (one
    minor version): it warns, naming the new one, and returns the same class."""
    import splatplan.encoders as encoders

    with pytest.warns(DeprecationWarning, match="EmbeddingDistance"):
        old = encoders.ImageCost
    assert old is EmbeddingDistance
