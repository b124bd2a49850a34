"""`splatplan encode`: output, --out, image modes, bad files and missing weights (exit 2, one line)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from splatplan.cli import main


@pytest.fixture()
def pngs(tmp_path, images):
    paths = []
    for i, im in enumerate(images[:3]):
        p = tmp_path / f"im{i}.png"
        Image.fromarray((im * 255).round().astype(np.uint8)).save(p)
        paths.append(str(p))
    return paths


def _err_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("splatplan: error:") and "\n" not in err, err
    return err


def test_encode_prints_dim_and_distances(pngs, tmp_path, capsys):
    out = tmp_path / "emb.npy"
    assert main(["encode", *pngs, "--encoder", "thumbnail", "--out", str(out), "--device", "cpu"]) == 0
    text = capsys.readouterr().out
    assert "thumbnail16-weight-free" in text and "dim 768" in text and "pairwise distances" in text
    emb = np.load(out)
    assert emb.shape == (3, 768) and emb.dtype == np.float32
    from splatplan.encoders import load_encoder
    from splatplan.encoders.images import load_image

    np.testing.assert_allclose(emb, load_encoder("thumbnail").encode(np.stack([load_image(p) for p in pngs])), atol=1e-6)


def test_encode_tokens_and_random_dinov2(pngs, capsys):
    args = ["encode", *pngs[:2], "--encoder", "dinov2-tiny", "--encoder-random-init", "true", "--encoder-image-size", "28", "--w-patch", "0.5", "--device", "cpu"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "dinov2-tiny-RANDOM-WEIGHTS" in text and "mean_p" in text


def test_image_modes(tmp_path, capsys):
    rng = np.random.default_rng(0)
    rgba = (rng.random((20, 24, 4)) * 255).astype(np.uint8)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "a.png")
    Image.fromarray(rgba[..., 0], "L").save(tmp_path / "g.png")
    from splatplan.encoders.images import load_image

    a = load_image(tmp_path / "a.png")
    np.testing.assert_allclose(a, rgba[..., :3] / 255 * (rgba[..., 3:] / 255), atol=1e-6)  # over black
    g = load_image(tmp_path / "g.png")
    assert g.shape == (20, 24, 3) and np.array_equal(g[..., 0], g[..., 2])
    assert main(["encode", str(tmp_path / "a.png"), str(tmp_path / "g.png"), "--encoder", "thumbnail"]) == 0
    capsys.readouterr()
    Image.fromarray((rng.random((8, 8)) * 65535).astype(np.uint16)).save(tmp_path / "i16.png")
    Image.fromarray(rgba[..., :3]).convert("CMYK").save(tmp_path / "c.jpg")
    for name in ("i16.png", "c.jpg"):
        assert main(["encode", str(tmp_path / name), "--encoder", "thumbnail"]) == 2
        assert "8-bit RGB" in _err_line(capsys)


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--encoder", "dinov2-vits14"], "facebook/dinov2-small"),
        (["--encoder", "dinov2-vits14", "--encoder-weights", "/nonexistent/dinov2"], "does not exist"),
        (["--encoder", "thumbnail", "--encoder-weights", "/tmp"], "weight-free"),
        (["--encoder", "thumbnail", "--out", "emb.txt"], ".npy"),
        (["--encoder", "thumbnail", "--w-patch", "-1"], "--w-patch"),
        (["--encoder", "dinov2-tiny", "--encoder-random-init", "true", "--encoder-image-size", "30"], "multiple of the 14"),
    ],
)
def test_bad_requests_exit_2(pngs, capsys, extra, match):
    assert main(["encode", pngs[0], *extra]) == 2
    assert match in _err_line(capsys)


def test_bad_image_files(tmp_path, pngs, capsys):
    junk = tmp_path / "junk.png"
    junk.write_text("not an image")
    trunc = tmp_path / "trunc.png"
    trunc.write_bytes(open(pngs[0], "rb").read()[:60])
    for p, match in ((junk, "not a readable image"), (trunc, "not a readable image"), (tmp_path / "nope.png", "does not exist"), (tmp_path, "not a file")):
        assert main(["encode", str(p), "--encoder", "thumbnail"]) == 2
        assert match in _err_line(capsys)
