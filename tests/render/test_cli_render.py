"""`splatplan render`: images, depth files, camera files and one-line errors (exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from splatplan.cli import main
from splatplan.render import look_at
from splatplan.scenes.load import save_scene

from .conftest import random_scene


@pytest.fixture(scope="module")
def scene_path(tmp_path_factory):
    p = tmp_path_factory.mktemp("scene") / "s.ply"
    save_scene(random_scene(150, sh_degree=1, disks=0.0, seed=3), p)  # a PLY holds 3DGS or 2DGS, not both
    return str(p)


def test_render_eye_look_at_with_depth(scene_path, tmp_path, capsys):
    out, dpng, dnpy = tmp_path / "a.png", tmp_path / "d.png", tmp_path / "d.npy"
    args = ["render", scene_path, "--eye", "3,0.5,1", "--look-at", "0,0,0", "--width", "48", "--height", "32", "--device", "cpu"]
    assert main(args + ["--out", str(out), "--depth", str(dpng)]) == 0
    img = np.asarray(Image.open(out))
    assert img.shape == (32, 48, 3) and img.dtype == np.uint8 and img.max() > 0
    d16 = np.asarray(Image.open(dpng))
    assert d16.shape == (32, 48) and d16.dtype == np.uint16
    assert main(args + ["--out", str(out), "--depth", str(dnpy)]) == 0
    d = np.load(dnpy)
    hit = d > 0
    assert hit.any() and np.all((d[hit] > 1.5) & (d[hit] < 5.0))  # splats lie 1.5..5 units from the eye
    np.testing.assert_allclose(d16[hit], np.rint(d[hit] * 1000), atol=1)
    assert "wrote" in capsys.readouterr().out


def test_render_from_viewmat_files_matches_look_at(scene_path, tmp_path):
    v = look_at([3.0, 0.5, 1.0], [0.0, 0.0, 0.0])
    k = [[40.0, 0.0, 24.0], [0.0, 40.0, 16.0], [0.0, 0.0, 1.0]]
    (tmp_path / "v.json").write_text(json.dumps({"viewmat": v.tolist()}))
    np.save(tmp_path / "v.npy", v[None])
    (tmp_path / "k.json").write_text(json.dumps(k))
    outs = []
    for vf in ("v.json", "v.npy"):
        out = tmp_path / f"{vf}.png"
        assert main(["render", scene_path, "--viewmat", str(tmp_path / vf), "--K", str(tmp_path / "k.json"),
                     "--width", "48", "--height", "32", "--out", str(out), "--device", "cpu"]) == 0  # fmt: skip
        outs.append(np.asarray(Image.open(out)))
    np.testing.assert_array_equal(outs[0], outs[1])


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--eye", "1,1,1", "--look-at", "1,1,1"], "coincide"),
        (["--eye", "nan,0,0", "--look-at", "0,0,0"], "finite"),
        (["--eye", "1,0,0"], "--look-at"),
        (["--eye", "1,0,0", "--look-at", "0,0,0", "--width", "0"], ">= 1 pixel"),
        (["--eye", "1,0,0", "--look-at", "0,0,0", "--width", "16000", "--height", "16000"], "GiB"),
        (["--eye", "1,0,0", "--look-at", "0,0,0", "--fov", "0"], "field of view"),
        (["--eye", "0,0,2", "--look-at", "0,0,0"], "parallel"),
        (["--viewmat", "VIEW_NAN"], "NaN"),
        (["--viewmat", "VIEW_SINGULAR"], "singular"),
        (["--viewmat", "VIEW_BATCH"], "one camera"),
        (["--viewmat", "MISSING.npy"], "does not exist"),
        (["--eye", "1,0,0", "--look-at", "0,0,0", "--K", "K_SINGULAR"], "singular"),
        (["--eye", "1,0,0", "--look-at", "0,0,0", "--background", "1,2"], "--background"),
        (["--eye", "1,0,0", "--look-at", "0,0,0", "--sh-degree", "7"], "sh_degree"),
    ],
)
def test_bad_input_exit_2(scene_path, tmp_path, capsys, extra, match):
    (tmp_path / "VIEW_NAN").with_suffix(".json").write_text(json.dumps([[float("nan")] * 4] * 4))  # Python writes NaN, which json.loads reads
    np.save(tmp_path / "VIEW_SINGULAR.npy", np.diag([1.0, 1.0, 0.0, 1.0]))
    np.save(tmp_path / "VIEW_BATCH.npy", np.stack([np.eye(4)] * 3))
    np.save(tmp_path / "K_SINGULAR.npy", np.zeros((3, 3)))
    names = {"VIEW_NAN": "VIEW_NAN.json", "VIEW_SINGULAR": "VIEW_SINGULAR.npy", "VIEW_BATCH": "VIEW_BATCH.npy", "K_SINGULAR": "K_SINGULAR.npy", "MISSING.npy": "MISSING.npy"}
    extra = [str(tmp_path / names[a]) if a in names else a for a in extra]
    out = tmp_path / "x.png"
    assert main(["render", scene_path, *extra, "--out", str(out), "--device", "cpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("splatplan: error:") and "\n" not in err and match in err, err
    assert not out.exists()
