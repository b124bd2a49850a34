"""The floater filter drops splats that are both faint and large, and only those."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes import FilterReport, filter_floaters, load_scene, save_scene

from .scene_encoders import random_splats


def _scene_with_floaters():
    s = random_splats(100, seed=0)
    s.scales[:] = 0.01  # median largest std 0.01
    s.opacities[:] = 0.9
    s.scales[0] = 0.2  # faint and large: floater
    s.opacities[0] = 0.05
    s.scales[1] = 0.2  # large but opaque: kept
    s.opacities[2] = 0.05  # faint but small: kept
    s.scales[3] = [0.01, 0.01, 0.06]  # faint, largest std 0.06 > 5 x 0.01: floater
    s.opacities[3] = 0.09
    return s


def test_both_conditions_needed():
    s = _scene_with_floaters()
    kept, report = filter_floaters(s)
    assert report == FilterReport(n_in=100, n_dropped=2, n_out=98, opacity_below=0.1, scale_factor=5.0, median_max_scale=pytest.approx(0.01), max_scale_above=pytest.approx(0.05))
    assert len(kept) == 98
    np.testing.assert_array_equal(kept.means, np.concatenate([s.means[1:3], s.means[4:]]))
    assert len(s) == 100  # input untouched


def test_thresholds_are_configurable():
    s = _scene_with_floaters()
    assert filter_floaters(s, opacity_below=0.08)[1].n_dropped == 1  # splat 3 (o = 0.09) kept
    assert filter_floaters(s, scale_factor=10.0)[1].n_dropped == 1  # splat 3 (6 x median) kept
    assert filter_floaters(s, opacity_below=0.0)[1].n_dropped == 0


@pytest.mark.parametrize("kw", [{"opacity_below": -0.1}, {"opacity_below": 1.5}, {"scale_factor": 0.0}])
def test_bad_thresholds(kw):
    with pytest.raises(SplatplanError):
        filter_floaters(random_splats(5), **kw)


def test_load_scene_records_report(tmp_path):
    save_scene(_scene_with_floaters(), tmp_path / "f.ply")
    s = load_scene(tmp_path / "f.ply")
    assert len(s) == 98
    assert s.info["floaters"]["n_dropped"] == 2 and s.info["floaters"]["opacity_below"] == 0.1
    assert len(load_scene(tmp_path / "f.ply", filter_floaters=False)) == 100
