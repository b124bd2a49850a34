"""benchmarks/vamp_compare.py: the VAMP comparator of the MBM speed benchmark.

The voxel thinning always runs; the end-to-end solve is skipped (with the reason) where VAMP does
not install or import (no wheel, no AVX2, no CPython 3.11) or the MBM data is absent."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

import vamp_compare as vc  # noqa: E402

MBM = REPO / ".." / "shared" / "data" / "mbm"


def test_thin_points_one_per_voxel_nearest_centre():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-0.3, 0.5, (4000, 3))
    v = 0.05
    out = vc.thin_points(pts, v)
    cells = np.floor(out / v).astype(np.int64)
    assert len(np.unique(cells, axis=0)) == len(out)  # one point per voxel
    assert len(out) == len(np.unique(np.floor(pts / v).astype(np.int64), axis=0))  # every occupied voxel kept
    assert np.all((out[:, None, :] == pts[None, :, :]).all(axis=2).any(axis=1))  # original points, not averages
    # the kept point is the one nearest its voxel's centre
    d_all = (((np.floor(pts / v) + 0.5) * v - pts) ** 2).sum(axis=1)
    key = {tuple(c): np.inf for c in cells}
    for c, d in zip(map(tuple, np.floor(pts / v).astype(np.int64)), d_all):
        key[c] = min(key[c], d)
    d_out = (((cells + 0.5) * v - out) ** 2).sum(axis=1)
    assert np.allclose(d_out, [key[tuple(c)] for c in cells])
    # deterministic, and independent of the input's order
    assert np.array_equal(out, vc.thin_points(pts, v))
    assert np.array_equal(out, vc.thin_points(pts[rng.permutation(len(pts))], v))


def test_thin_points_edge_cases():
    pts = np.array([[0.001, 0.001, 0.001], [0.009, 0.009, 0.009], [0.0051, 0.005, 0.005], [0.031, 0.0, 0.0]])
    out = vc.thin_points(pts, 0.01)
    assert out.tolist() == [[0.0051, 0.005, 0.005], [0.031, 0.0, 0.0]]  # nearest (0.005, 0.005, 0.005) wins its voxel
    assert np.array_equal(vc.thin_points(pts, 0.0), pts)  # no thinning
    assert vc.thin_points(np.zeros((0, 3)), 0.02).shape == (0, 3)
    same = np.array([[0.2, 0.2, 0.2]] * 3)
    assert vc.thin_points(same, 0.02).shape == (1, 3)


def test_vamp_python_reports_a_missing_wheel(tmp_path, monkeypatch):
    monkeypatch.setenv(vc.WHEEL_ENV, str(tmp_path / "nope.whl"))
    py, why = vc.vamp_python(str(tmp_path / "venv"))  # a fresh venv folder: nothing to reuse
    assert py is None and why  # never raises; says why


def _check(r, p, mode):
    keys = {"family", "index", "solved", "plan_s", "simplify_s", "path", "build_s", "n_points", "start_valid", "goal_valid"}
    assert keys <= set(r), keys - set(r)
    assert (r["family"], r["index"]) == (p["family"], p["index"])
    assert r["start_valid"] and r["goal_valid"], r
    assert r["solved"], r
    assert 0 < r["plan_s"] < 1.0 and 0 <= r["simplify_s"] < 1.0
    path = np.asarray(r["path"])
    assert path.ndim == 2 and path.shape[1] == 7 and len(path) >= 2
    assert np.array_equal(path[0], p["q_start"]) and np.array_equal(path[-1], p["q_goal"])
    if mode == "capt":
        assert 0 < r["n_points"] <= r["n_points_raw"] and r["build_s"] > 0
        assert 0 < r["r_min"] < r["r_max"]
    else:
        assert r["build_s"] == 0 and r["n_points"] == 0


def test_vamp_solves_an_mbm_problem_exact_and_capt():
    if not (MBM / "problems").is_dir():
        pytest.skip(f"MBM data not found at {MBM}")
    py, why = vc.vamp_python()
    if py is None:
        pytest.skip(f"VAMP unavailable: {why}")
    problems, _ = vc.load_problems(["table_pick"], 1)
    p = problems[0]
    meta: dict = {}
    r = vc.solve_vamp(py, [p], "exact", meta=meta)[0]
    _check(r, p, "exact")
    assert meta["planner"] == "rrtc" and meta["n_spheres"] == 59
    pc = dict(p, points=vc.scene_points(p["objects"], 30_000))
    r = vc.solve_vamp(py, [pc], "capt", thin_m=0.02, meta=meta)[0]
    _check(r, p, "capt")
    assert r["n_points"] == len(vc.thin_points(pc["points"], 0.02))
    assert meta["r_max"] == pytest.approx(0.08, abs=1e-6)
