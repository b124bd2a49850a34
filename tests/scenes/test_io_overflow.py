"""Values that overflow float32 after activation are bad input naming the field and row, and no
numpy RuntimeWarning reaches the user: not from the library (warnings are errors in this module)
and not from the CLI (run with ``-W error``, stderr checked)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import plyfile
import pytest

from splatplan.errors import SceneFormatError
from splatplan.scenes import load_scene, save_scene

from .scene_encoders import random_splats, write_compressed_ply

pytestmark = pytest.mark.filterwarnings("error")  # any RuntimeWarning fails the test


def _edit_ply(path: Path, edit, n: int = 20, seed: int = 1) -> Path:
    """A small INRIA ply with some values changed by ``edit(vertex_data)``."""
    save_scene(random_splats(n, seed=seed), path)
    ply = plyfile.PlyData.read(str(path), mmap=False)
    data = ply["vertex"].data.copy()
    edit(data)
    plyfile.PlyData([plyfile.PlyElement.describe(data, "vertex")]).write(str(path))
    return path


def _big_scale(a):
    a["scale_0"][3] = 100.0  # exp(100) = 2.7e43 > float32 max


def _edit_compressed(path: Path, edit, n: int = 600) -> Path:
    write_compressed_ply(random_splats(n, seed=2), path)
    ply = plyfile.PlyData.read(str(path), mmap=False)
    chunk = ply["chunk"].data.copy()
    edit(chunk)
    plyfile.PlyData([plyfile.PlyElement.describe(chunk, "chunk"), ply["vertex"]]).write(str(path))
    return path


def test_inria_log_scale_overflow_names_field_and_row(tmp_path):
    path = _edit_ply(tmp_path / "big.ply", _big_scale)
    with pytest.raises(
        SceneFormatError,
        match=r"big\.ply: 1 of 20 splat\(s\) have NaN/Inf in 'scales' \(first at index 3\) after activation \(std = exp\(scale_\*\); log-scales above 88\.7 overflow",
    ):
        load_scene(path)


def test_inria_largest_finite_log_scale_loads(tmp_path):
    def edit(a):
        a["scale_1"][5] = 88.0  # exp(88) = 1.65e38 fits float32

    s = load_scene(_edit_ply(tmp_path / "ok.ply", edit), filter_floaters=False)
    assert np.isfinite(s.scales).all() and s.scales[5, 1] > 1e38


def test_overflow_dropped_with_drop_invalid(tmp_path):
    s = load_scene(_edit_ply(tmp_path / "big.ply", _big_scale), drop_invalid=True, filter_floaters=False)
    assert len(s) == 19 and np.isfinite(s.scales).all()
    assert s.info["invalid_dropped"] == {"NaN/Inf in 'scales'": 1, "total": 1}


def test_inria_double_precision_means_beyond_float32(tmp_path):
    save_scene(random_splats(10, seed=3), tmp_path / "d.ply")
    data = plyfile.PlyData.read(str(tmp_path / "d.ply"), mmap=False)["vertex"].data
    wide = np.empty(len(data), dtype=[(f, "<f8" if f in "xyz" else "<f4") for f in data.dtype.names])
    for f in data.dtype.names:
        wide[f] = data[f]
    wide["z"][7] = 1e39
    plyfile.PlyData([plyfile.PlyElement.describe(wide, "vertex")]).write(str(tmp_path / "d.ply"))
    with pytest.raises(SceneFormatError, match=r"1 of 10 splat\(s\) have NaN/Inf in 'means' \(first at index 7\)"):
        load_scene(tmp_path / "d.ply")


def test_compressed_ply_inf_chunk_scale(tmp_path):
    def edit(chunk):
        chunk["max_scale_x"][1] = np.inf  # chunk 1 holds splats 256..511

    with pytest.raises(SceneFormatError, match=r"c\.ply: 256 of 600 splat\(s\) have NaN/Inf in 'scales' \(first at index 256\) after activation \(exp of the lerp"):
        load_scene(_edit_compressed(tmp_path / "c.ply", edit))


def test_compressed_ply_inf_chunk_position(tmp_path):
    def edit(chunk):
        chunk["min_y"][2], chunk["max_y"][2] = -np.inf, np.inf

    with pytest.raises(SceneFormatError, match=r"88 of 600 splat\(s\) have NaN/Inf in 'means' \(first at index 512\)"):
        load_scene(_edit_compressed(tmp_path / "c.ply", edit))


def test_checkpoint_overflow(tmp_path):
    torch = pytest.importorskip("torch")
    n = 8
    params = {
        "means": torch.zeros(n, 3, dtype=torch.float64),
        "quats": torch.ones(n, 4),
        "scales": torch.full((n, 3), -3.0),
        "opacities": torch.zeros(n),
        "sh0": torch.zeros(n, 1, 3),
    }
    params["scales"][6, 2] = 120.0
    torch.save({"splats": params}, tmp_path / "o.pt")
    with pytest.raises(SceneFormatError, match=r"1 of 8 splat\(s\) have NaN/Inf in 'scales' \(first at index 6\) after activation \(std = exp\(scales\)"):
        load_scene(tmp_path / "o.pt")
    params["scales"][6, 2] = -3.0
    params["means"][2, 0] = 1e300
    torch.save({"splats": params}, tmp_path / "m.pt")
    with pytest.raises(SceneFormatError, match=r"NaN/Inf in 'means' \(first at index 2\)"):
        load_scene(tmp_path / "m.pt")


# ----------------------------------------------------------------------------- the CLI
def _cli(*args: str) -> subprocess.CompletedProcess:
    """Run ``splatplan ARGS`` with every Python warning turned into an error."""
    return subprocess.run([sys.executable, "-W", "error", "-m", "splatplan.cli", *args], capture_output=True, text=True, timeout=120)


def _assert_one_line_error(res: subprocess.CompletedProcess, pattern: str) -> None:
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("splatplan: error: "), res.stderr
    assert "Warning" not in res.stderr and "Traceback" not in res.stderr
    assert pattern in lines[0], lines[0]


def test_cli_info_and_check_on_overflowing_files(tmp_path):
    big = _edit_ply(tmp_path / "big.ply", _big_scale)
    comp = _edit_compressed(tmp_path / "c.ply", lambda c: c.__setitem__("max_scale_z", np.full(len(c), np.inf)))
    np.save(tmp_path / "poses.npy", np.zeros((4, 3)))
    _assert_one_line_error(_cli("info", str(big)), "'scales' (first at index 3)")
    _assert_one_line_error(_cli("check", str(big), "--poses", str(tmp_path / "poses.npy"), "--robot", "sphere:0.05"), "'scales' (first at index 3)")
    _assert_one_line_error(_cli("info", str(comp)), "'scales' (first at index 0)")


def test_cli_info_extreme_but_valid_values_is_silent(tmp_path):
    def edit(a):
        a["scale_1"][5] = 88.0
        a["opacity"][2] = 1e30  # sigmoid -> 1 without overflow
        a["opacity"][4] = -1e30

    res = _cli("info", str(_edit_ply(tmp_path / "ok.ply", edit)))
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""
    assert "20 splats" in res.stdout
