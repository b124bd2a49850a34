"""Real trained scenes: the banana fixture (in the repo) and the truck and bathroom files that are
read from ``<repo>/../shared/data/real/`` and skipped when that folder is absent."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import plyfile
import pytest
from scipy.spatial import cKDTree

from splatplan.scenes import Splats, filter_floaters, load_scene

REPO = Path(__file__).resolve().parents[2]
BANANA = REPO / "tests" / "data" / "equinor_banana_splat.ply"
SHARED_REAL = REPO / ".." / "shared" / "data" / "real"
TRUCK = SHARED_REAL / "uav4geo_truck.splat"
BATHROOM = SHARED_REAL / "ARVR_Apartments_Toilet.compressed.ply"

needs_truck = pytest.mark.skipif(not TRUCK.exists(), reason=f"{TRUCK} not present")
needs_bathroom = pytest.mark.skipif(not BATHROOM.exists(), reason=f"{BATHROOM} not present")


def assert_sane(s: Splats, n: int) -> None:
    assert len(s) == n
    for name in ("means", "quats", "scales", "opacities", "colors"):
        assert np.all(np.isfinite(getattr(s, name))), name
    np.testing.assert_allclose(np.linalg.norm(s.quats, axis=1), 1.0, atol=1e-6)
    assert np.all(s.scales > 0)
    assert np.all((s.opacities >= 0) & (s.opacities <= 1))
    s.validate()


def thin_axis_alignment(s: Splats, quats: np.ndarray, n_sample: int = 2000) -> float:
    """Median |cos| between flat opaque splats' thinnest axis and the PCA normal of their 16 nearest means.

    Trained splats lie flat on surfaces, so the right quaternion convention gives values near 1;
    a wrong component order scatters the axes (about 0.5 for random directions).
    """
    srt = np.sort(s.scales, axis=1)
    flat = np.nonzero((srt[:, 0] < 0.2 * srt[:, 1]) & (s.opacities > 0.5))[0]
    idx = np.random.default_rng(0).choice(flat, min(n_sample, flat.size), replace=False)
    means = s.means.astype(np.float64)
    _, nb = cKDTree(means).query(means[idx], k=16)
    pts = means[nb] - means[nb].mean(axis=1, keepdims=True)  # (M, 16, 3)
    normals = np.linalg.eigh(np.einsum("mki,mkj->mij", pts, pts))[1][:, :, 0]  # (M, 3)
    rot = Splats(means=means[idx], quats=quats[idx], scales=s.scales[idx], opacities=s.opacities[idx], colors=s.colors[idx]).rotations()
    thin = rot[np.arange(idx.size), :, np.argmin(s.scales[idx], axis=1)]  # (M, 3) local thin axis in world
    return float(np.median(np.abs(np.sum(thin * normals, axis=1))))


def test_banana_inria_ply_shuffled_fields():
    s = load_scene(BANANA, filter_floaters=False)
    assert s.source_format == "inria"
    assert_sane(s, 11_458)
    assert s.sh_rest is not None and s.sh_rest.shape == (11_458, 15, 3)
    lo, hi = s.bounds()
    assert 0.4 < np.max(hi - lo) < 0.5  # "about 0.46 units long"
    assert np.median(s.scales) < 0.01
    assert thin_axis_alignment(s, s.quats) > 0.65


@needs_truck
def test_truck_splat():
    s = load_scene(TRUCK, filter_floaters=False)
    assert s.source_format == "splat"
    assert_sane(s, 116_544)
    lo, hi = s.bounds()
    assert 2.0 < np.max(hi - lo) < 5.0  # "normalised to about 3 units"
    assert np.median(s.scales) < 0.05


@needs_bathroom
def test_bathroom_compressed_ply():
    s = load_scene(BATHROOM, filter_floaters=False)
    assert s.source_format == "compressed_ply"
    assert_sane(s, 57_574)
    assert s.sh_rest is not None and s.sh_rest.shape == (57_574, 15, 3)
    assert 1e-4 < np.median(s.scales) < 0.1  # roughly metric room scan: millimetres to centimetres
    # every mean lies inside its chunk's bounds
    chunk = plyfile.PlyData.read(str(BATHROOM))["chunk"].data
    ci = np.arange(len(s)) // 256
    for j, a in enumerate("xyz"):
        assert np.all(s.means[:, j] >= chunk[f"min_{a}"][ci] - 1e-5)
        assert np.all(s.means[:, j] <= chunk[f"max_{a}"][ci] + 1e-5)
    # the packed quaternion is wxyz (index 0 = w): the thin axes follow the surfaces, and reading
    # the components as xyzw instead does visibly worse
    q = s.quats.astype(np.float64)
    right, wrong = thin_axis_alignment(s, q), thin_axis_alignment(s, np.concatenate([q[:, 3:], q[:, :3]], axis=1))
    assert right > 0.9 and right > wrong + 0.1


@needs_bathroom
def test_bathroom_floater_filter():
    raw = load_scene(BATHROOM, filter_floaters=False)
    kept, report = filter_floaters(raw)
    assert report.n_in == 57_574 and report.n_out == len(kept) == report.n_in - report.n_dropped
    assert 100 < report.n_dropped < 1000  # the scan has many faint, large floaters (298 here)
    max_s = raw.scales.max(axis=1)
    dropped = (raw.opacities < 0.1) & (max_s > 5 * np.median(max_s))
    assert report.n_dropped == int(dropped.sum())
    loaded = load_scene(BATHROOM)
    assert len(loaded) == report.n_out
    assert loaded.info["floaters"]["n_dropped"] == report.n_dropped
    stricter = load_scene(BATHROOM, floater_opacity=0.3, floater_scale_factor=3.0)
    assert stricter.info["floaters"]["n_dropped"] > report.n_dropped
