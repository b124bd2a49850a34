"""DINOv2 encoders: random-initialised forward passes, pooling options, weights-folder errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from splatplan.encoders import load_encoder
from splatplan.encoders.dinov2 import ARCHS, Dinov2Encoder, dinov2_config
from splatplan.errors import SplatplanError


def test_tiny_forward_and_poolings(tiny_dinov2, images):
    assert tiny_dinov2.name == "dinov2-tiny-RANDOM-WEIGHTS"
    assert tiny_dinov2.n_tokens == 16 and tiny_dinov2.dim == 48
    x = torch.from_numpy(images)
    cls = tiny_dinov2.encode(x)
    tok = tiny_dinov2.encode_tokens(x)
    assert cls.shape == (4, 48) and tok.shape == (4, 16, 48)
    # the same model with the other poolings gives the mean of the patch tokens / both concatenated
    mean = Dinov2Encoder(tiny_dinov2.model, "m", pooling="mean", image_size=56).encode(x)
    both = Dinov2Encoder(tiny_dinov2.model, "b", pooling="cls_mean", image_size=56).encode(x)
    torch.testing.assert_close(mean, tok.mean(dim=1), rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(both, torch.cat([cls, mean], dim=1), rtol=1e-5, atol=1e-5)
    # the CLS output is the model's own pooler output on the preprocessed input
    from splatplan.encoders.preprocess import imagenet_normalize, resize

    pix = imagenet_normalize(resize(x.permute(0, 3, 1, 2), (56, 56)))
    with torch.no_grad():
        torch.testing.assert_close(cls, tiny_dinov2.model(pixel_values=pix).pooler_output, rtol=1e-5, atol=1e-5)
    assert cls.std() > 0 and not torch.allclose(cls[0], cls[1])


def test_vits14_random_init_has_the_real_architecture():
    enc = load_encoder("dinov2-vits14", random_init=True, image_size=28)
    assert enc.name == "dinov2-vits14-RANDOM-WEIGHTS" and enc.dim == 384
    n_params = sum(p.numel() for p in enc.model.parameters())
    assert 21e6 < n_params < 23e6  # ViT-S/14: ~22M parameters
    e = enc.encode(np.random.default_rng(0).random((2, 28, 28, 3)).astype(np.float32))
    assert e.shape == (2, 384) and np.isfinite(e).all()


def test_configs_of_named_architectures():
    for name in ("dinov2-vits14", "dinov2-vitb14", "dinov2-vitl14"):
        cfg = dinov2_config(name)
        assert (cfg.hidden_size, cfg.num_hidden_layers, cfg.num_attention_heads) == tuple(ARCHS[name][k] for k in ("hidden_size", "num_hidden_layers", "num_attention_heads"))
        assert cfg.patch_size == 14 and cfg.mlp_ratio == 4


def _one_line(exc_info) -> str:
    msg = str(exc_info.value)
    assert "\n" not in msg
    return msg


def test_missing_weights_say_what_to_put_where(tmp_path):
    for weights in (None, tmp_path / "nope"):
        with pytest.raises(SplatplanError) as ei:
            load_encoder("dinov2-vits14", weights=weights)
        msg = _one_line(ei)
        assert "facebook/dinov2-small" in msg and "save_pretrained" in msg and "config.json" in msg
    with pytest.raises(SplatplanError, match="facebook/dinov2-base"):
        load_encoder("dinov2-vitb14")
    f = tmp_path / "file.bin"
    f.write_bytes(b"x")
    with pytest.raises(SplatplanError, match="is a file"):
        load_encoder("dinov2-vits14", weights=f)
    with pytest.raises(SplatplanError, match="no config.json"):
        load_encoder("dinov2-vits14", weights=tmp_path)


def test_wrong_architecture_folders(tmp_path, tiny_dinov2):
    d = tmp_path / "tiny"
    tiny_dinov2.model.save_pretrained(d)
    # any DINOv2: loads, same outputs as the saved model
    x = np.random.default_rng(0).random((2, 56, 56, 3)).astype(np.float32)
    enc = load_encoder("dinov2", weights=d, image_size=56)
    np.testing.assert_allclose(enc.encode(x), tiny_dinov2.encode(x), atol=1e-5)
    assert "RANDOM" not in enc.name  # loaded from a folder; the folder's content is the user's claim
    # a named architecture that the folder does not hold
    with pytest.raises(SplatplanError) as ei:
        load_encoder("dinov2-vits14", weights=d)
    assert "not dinov2-vits14" in _one_line(ei) and "hidden_size 48" in str(ei.value)
    # not a DINOv2 at all
    v = tmp_path / "vit"
    v.mkdir()
    (v / "config.json").write_text(json.dumps({"model_type": "vit", "hidden_size": 384}))
    with pytest.raises(SplatplanError, match="'vit' model, not DINOv2"):
        load_encoder("dinov2-vits14", weights=v)
    # the right config but no weights file
    s = tmp_path / "small"
    s.mkdir()
    dinov2_config("dinov2-vits14").to_json_file(str(s / "config.json"))
    with pytest.raises(SplatplanError, match="no model.safetensors"):
        load_encoder("dinov2-vits14", weights=s)
    # a config that does not fit its weights file, a corrupt weights file, a broken config
    m = tmp_path / "mix"
    m.mkdir()
    cfg = json.loads((d / "config.json").read_text())
    (m / "config.json").write_text(json.dumps({**cfg, "hidden_size": 60, "num_attention_heads": 4}))
    (m / "model.safetensors").write_bytes((d / "model.safetensors").read_bytes())
    with pytest.raises(SplatplanError) as ei:
        load_encoder("dinov2", weights=m)
    _one_line(ei)
    (m / "model.safetensors").write_bytes(b"garbage")
    with pytest.raises(SplatplanError, match="cannot load DINOv2 weights"):
        load_encoder("dinov2", weights=m)
    (m / "config.json").write_text("{not json")
    with pytest.raises(SplatplanError, match="not a readable JSON"):
        load_encoder("dinov2", weights=m)


def test_random_init_rules(tmp_path):
    with pytest.raises(SplatplanError, match="exclude each other"):
        load_encoder("dinov2-vits14", random_init=True, weights=tmp_path)
    with pytest.raises(SplatplanError, match="name one"):
        load_encoder("dinov2", random_init=True)
    with pytest.raises(SplatplanError, match="only with random weights"):
        load_encoder("dinov2-tiny", weights=tmp_path)
