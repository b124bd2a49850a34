"""The command line: outputs, and bad input -> clear message, exit code 2, no traceback, nothing half-written."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main

DATA = Path(__file__).parent / "data"
BANANA = DATA / "equinor_banana_splat.ply"


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """Run the installed console entry point in a fresh process (checks banners and tracebacks)."""
    return subprocess.run([sys.executable, "-m", "splatplan.cli", *args], capture_output=True, text=True, timeout=300)


def test_info_json(capsys):
    assert main(["info", str(BANANA), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["count"] == 11458
    assert info["format"] == "inria"
    assert len(info["bounds_min"]) == 3 and len(info["bounds_max"]) == 3
    assert all(a < b for a, b in zip(info["bounds_min"], info["bounds_max"]))


def test_check_writes_all_outputs(tmp_path, capsys):
    rng = np.random.default_rng(0)
    poses = np.concatenate([rng.uniform(-0.2, 0.2, (50, 3)), np.tile([1.0, 0, 0, 0], (50, 1))], axis=1)
    np.save(tmp_path / "poses.npy", poses)
    out = tmp_path / "res.npz"
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "poses.npy"), "--robot", "ellipsoid:0.02,0.01,0.03",
                 "--n-sigma", "1.5", "--out", str(out)]) == 0  # fmt: skip
    res = np.load(out)
    for k in ("min_s2", "n_colliding", "in_collision", "softmin", "cost"):
        assert res[k].shape == (50,), k
    np.save(tmp_path / "p3.npy", poses[:, :3])
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "p3.npy"), "--robot", "sphere:0.02"]) == 0


def test_subprocess_is_quiet_and_clean(tmp_path):
    np.save(tmp_path / "p.npy", np.zeros((4, 3)))
    r = run_cli("check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01")
    assert r.returncode == 0, r.stderr
    assert "Warp" not in r.stdout + r.stderr  # no banner, no CUDA-driver warning
    assert r.stdout.strip().startswith("4 poses checked")


BAD_POSES = {
    "nan": np.array([[0.0, np.nan, 0.0]]),
    "shape": np.zeros((5, 4)),
    "ndim": np.zeros(3),
    "zero_quat": np.zeros((2, 7)),
    "strings": np.array([["a", "b", "c"]]),
}


@pytest.mark.parametrize("case", sorted(BAD_POSES))
def test_bad_poses_exit_2(tmp_path, case):
    np.save(tmp_path / "p.npy", BAD_POSES[case])
    out = tmp_path / "o.npz"
    r = run_cli("check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(out))
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.startswith("splatplan: error:") and "poses" in r.stderr
    assert not out.exists()


def test_bad_inputs_exit_2(tmp_path):
    trunc = tmp_path / "trunc.ply"
    trunc.write_bytes(BANANA.read_bytes()[:5000])
    (tmp_path / "junk.npy").write_bytes(b"not an npy file")
    np.save(tmp_path / "p.npy", np.zeros((2, 3)))
    cases = [
        (["info", str(trunc)], "trunc.ply"),
        (["info", str(tmp_path / "missing.ply")], "missing.ply"),
        (["check", str(BANANA), "--poses", str(tmp_path / "junk.npy"), "--robot", "sphere:0.01"], "junk.npy"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "cube:1"], "--robot"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:-1"], "--robot"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--n-sigma", "-1"], "n_sigma"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(tmp_path / "nodir" / "o.npz")], "nodir"),
        (["scene", "stonehenge", "--out", str(tmp_path / "s.ply"), "--level", "9"], "--level"),
        (["scene", "atlantis", "--out", str(tmp_path / "s.ply")], "atlantis"),
    ]
    for argv, needle in cases:
        r = run_cli(*argv)
        assert r.returncode == 2, (argv, r.stderr)
        assert "Traceback" not in r.stderr, r.stderr
        assert needle in r.stderr, (needle, r.stderr)
    assert sorted(os.listdir(tmp_path)) == ["junk.npy", "p.npy", "trunc.ply"]  # nothing half-written


def test_existing_output_survives_a_failed_run(tmp_path):
    out = tmp_path / "o.npz"
    out.write_bytes(b"precious")
    np.save(tmp_path / "p.npy", np.array([[np.inf, 0, 0]]))
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(out)]) == 2
    assert out.read_bytes() == b"precious"


def test_scene_stonehenge_writes_ply_and_ground_truth(tmp_path, capsys):
    out = tmp_path / "sh.ply"
    assert main(["scene", "stonehenge", "--out", str(out), "--level", "5", "--seed", "1"]) == 0
    assert out.exists() and (tmp_path / "sh.gt.json").exists()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["count"] > 1000


def _write_ply(path: Path, fields: dict[str, np.ndarray]) -> None:
    from plyfile import PlyData, PlyElement

    n = len(next(iter(fields.values())))
    arr = np.zeros(n, dtype=[(k, "f4") for k in fields])
    for k, v in fields.items():
        arr[k] = v
    PlyData([PlyElement.describe(arr, "vertex")]).write(str(path))


def test_broken_scene_files_exit_2(tmp_path):
    n = 20
    good = {"x": np.zeros(n), "y": np.zeros(n), "z": np.zeros(n), "f_dc_0": np.zeros(n), "f_dc_1": np.zeros(n), "f_dc_2": np.zeros(n),
            "opacity": np.zeros(n), "scale_0": np.full(n, -4.0), "scale_1": np.full(n, -4.0), "scale_2": np.full(n, -4.0),
            "rot_0": np.ones(n), "rot_1": np.zeros(n), "rot_2": np.zeros(n), "rot_3": np.zeros(n)}  # fmt: skip
    missing = {k: v for k, v in good.items() if k != "opacity"}
    nan = dict(good, x=np.where(np.arange(n) == 3, np.nan, 0.0))
    zero_q = dict(good, rot_0=np.zeros(n))
    np.save(tmp_path / "p.npy", np.zeros((2, 3)))
    for name, fields, needle in (("missing", missing, "opacity"), ("nan", nan, "NaN"), ("zeroq", zero_q, "quaternion")):
        _write_ply(tmp_path / f"{name}.ply", fields)
        for argv in (["info", str(tmp_path / f"{name}.ply")],
                     ["check", str(tmp_path / f"{name}.ply"), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01"]):  # fmt: skip
            r = run_cli(*argv)
            assert r.returncode == 2, (name, r.stderr)
            assert "Traceback" not in r.stderr and needle in r.stderr, (name, r.stderr)
    _write_ply(tmp_path / "ok.ply", good)
    assert run_cli("info", str(tmp_path / "ok.ply")).returncode == 0
