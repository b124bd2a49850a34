"""EfficientNet-Lite0: our model definition loads the packaged ImageNet weights strictly, its
features are deterministic and non-degenerate, and its ImageNet predictions are sane.

What is checked about the predictions (ImageNet-1k class indices):
* the Grace Hopper photograph shipped with matplotlib -> 652 "military uniform" (top-1);
* an 8 x 8 black/white checkerboard (28-px squares) -> 918 "crossword puzzle" (top-1);
* a red disk on white -> 722 "ping-pong ball" or 417 "balloon" in the top 2;
* a uniform grey image -> no confident class (max p < 0.01).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from splatplan.encoders import load_encoder
from splatplan.encoders.efficientnet_lite import EfficientNetLite0, build_model, load_state_dict, pad_same
from splatplan.errors import SplatplanError

from .conftest import needs_effnet_weights

needs_effnet_weights()  # every test here reads the packaged ImageNet weights

MILITARY_UNIFORM, CROSSWORD, PING_PONG_BALL, BALLOON = 652, 918, 722, 417


@pytest.fixture(scope="module")
def effnet224():
    return load_encoder("efficientnet-lite0")


def test_strict_load_covers_every_tensor():
    sd = load_state_dict()
    model = EfficientNetLite0()
    assert set(model.state_dict()) == set(sd)  # same names
    assert all(model.state_dict()[k].shape == v.shape for k, v in sd.items())
    m = build_model()
    torch.testing.assert_close(m._conv_head.weight, sd["_conv_head.weight"])
    assert sum(p.numel() for p in m.parameters()) == 4_652_008  # EfficientNet-Lite0: 4.65M parameters


def test_broken_state_dicts_are_one_line_errors(tmp_path):
    sd = load_state_dict()
    del sd["_fc.bias"]
    torch.save(sd, tmp_path / "missing.pth")
    with pytest.raises(SplatplanError, match="strict load") as ei:
        build_model(tmp_path / "missing.pth")
    assert "\n" not in str(ei.value)
    (tmp_path / "junk.pth").write_bytes(b"junk")
    with pytest.raises(SplatplanError, match="not a readable torch state dict"):
        build_model(tmp_path / "junk.pth")
    with pytest.raises(SplatplanError, match="does not exist"):
        build_model(tmp_path / "nope.pth")


def test_pad_same_is_tensorflow_same():
    for size in (7, 8, 9, 224, 225):
        for k, s in ((3, 2), (5, 2), (3, 1), (5, 1), (1, 1)):
            x = torch.zeros(1, 1, size, size)
            out = torch.nn.functional.conv2d(pad_same(x, k, s), torch.zeros(1, 1, k, k), stride=s)
            assert out.shape[-1] == -(-size // s)  # ceil(size / s), as TF 'SAME'
    # stride 2 on an even size pads only bottom/right (TF), not symmetrically
    x = torch.arange(16.0).view(1, 1, 4, 4)
    p = pad_same(x, 3, 2)
    assert p.shape[-1] == 5 and torch.equal(p[..., :4, :4], x)


def test_features_deterministic_and_non_degenerate(effnet, images):
    a, b = effnet.encode(images), effnet.encode(images)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (4, 1280) and np.isfinite(a).all() and (a >= 0).all() and (a <= 6).all()  # ReLU6 features
    assert (a.std(axis=0) > 0).sum() > 100  # many feature channels vary over images
    d = effnet.image_cost(a[0], a)
    assert d[0] == 0 and (d[1:] > 1e-3).all()
    tok = effnet.encode_tokens(images)
    assert tok.shape == (4, 9, 1280)
    np.testing.assert_allclose(tok.mean(axis=1), a, rtol=1e-5, atol=1e-6)  # pooled = mean of the 3x3 grid


def _probs(enc, img):
    return torch.from_numpy(enc.classify(img[None].astype(np.float32))).softmax(-1)[0]


def test_imagenet_predictions_are_sane(effnet224):
    yy, xx = np.mgrid[0:224, 0:224]
    checker = np.repeat((((yy // 28) + (xx // 28)) % 2)[..., None], 3, axis=-1)
    assert int(_probs(effnet224, checker).argmax()) == CROSSWORD
    disk = np.ones((224, 224, 3))
    disk[(yy - 112) ** 2 + (xx - 112) ** 2 < 60**2] = (1, 0, 0)
    top2 = _probs(effnet224, disk).topk(2).indices.tolist()
    assert PING_PONG_BALL in top2 or BALLOON in top2
    assert float(_probs(effnet224, np.full((224, 224, 3), 0.5)).max()) < 0.01


def test_grace_hopper_is_a_military_uniform(effnet224):
    mpl = pytest.importorskip("matplotlib")
    path = Path(mpl.get_data_path()) / "sample_data" / "grace_hopper.jpg"
    if not path.is_file():
        pytest.skip("matplotlib sample data not installed")
    from splatplan.encoders.images import load_image

    p = _probs(effnet224, load_image(path))
    assert int(p.argmax()) == MILITARY_UNIFORM and float(p.max()) > 0.2
