"""The built-in apartment's real-capture look (issue #36): haze, a mirror layer under a shiny floor,
floor-level matter; and what the default metric makes of it for a Go2 and a small sphere."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes.builtin import build_builtin
from splatplan.scenes.builtin.apartment import HAZE, ROOMS, room_of
from splatplan.scenes.filters import filter_floaters


@pytest.fixture(scope="module")
def hazy():
    return build_builtin("apartment", haze=True)


def _kinds(splats):
    """name -> slice of the capture-look splats (they sit between the surface splats and the floaters)."""
    look = splats.info["capture_look"]
    start = len(splats) - int(splats.info["n_floaters"]) - sum(look.values())
    out = {}
    for k, n in look.items():
        out[k] = slice(start, start + n)
        start += n
    return out


def test_haze_has_the_statistics_of_real_apartment_captures(hazy):
    splats, scene = hazy
    plain, _ = build_builtin("apartment")
    o = splats.opacities
    assert 0.06 <= (o < 0.1).mean() <= 0.09  # the 6-9% below 0.1
    assert 0.12 <= (o < 0.3).mean() <= 0.15  # and 12-15% below 0.3
    k = _kinds(splats)
    h = k["haze"]
    assert HAZE["haze_opacity"][0] <= o[h].min() and o[h].max() <= HAZE["haze_opacity"][1]
    z = splats.means[h, 2]
    assert z.min() >= 0.10 - 1e-6 and z.max() <= 0.40 + 1e-6
    big = splats.scales[h].max(axis=1)
    assert big.min() >= 0.06 * 0.99 and big.max() <= 0.15 * 1.01
    assert all(room_of(m) is not None for m in splats.means[h][:500, :2])
    # the surface splats and floaters are the plain apartment's, unchanged
    n_surf = len(plain) - int(plain.info["n_floaters"])
    np.testing.assert_array_equal(splats.means[:n_surf], plain.means[:n_surf])
    np.testing.assert_array_equal(splats.means[-int(plain.info["n_floaters"]):], plain.means[n_surf:])
    # the default floater filter keeps the haze (it is not large against this scene's median), as on real captures
    kept, rep = filter_floaters(splats)
    assert rep.n_dropped <= int(plain.info["n_floaters"])
    assert (kept.opacities < 0.1).sum() >= 0.95 * (h.stop - h.start)


def test_mirror_layer_lies_under_the_shiny_floor_only(hazy):
    splats, _ = hazy
    m = _kinds(splats)["mirror"]
    assert m.stop - m.start > 500
    z = splats.means[m, 2]
    assert z.max() < 0.0 and z.min() >= -HAZE["mirror_reach"]
    assert (splats.opacities[m] >= 0.5).all()  # opaque: trained as geometry
    assert splats.scales[m].max() <= HAZE["mirror_std_max"] * 1.0001
    assert {room_of(p) for p in splats.means[m][:, :2]} == set(HAZE["mirror_rooms"])
    lo, hi = ROOMS["living"]
    below = (splats.means[:, 2] < -0.15) & (splats.means[:, 0] < hi[0])  # (fringe splats of the floor lie within a few cm)
    assert not below.any()  # no reflection under the living room's matt floor


def test_haze_is_seeded_and_only_the_apartment_has_it():
    a, _ = build_builtin("apartment", seed=1, haze=True)
    b, _ = build_builtin("apartment", seed=1, haze=True)
    np.testing.assert_array_equal(a.means, b.means)
    for name in ("tabletop", "stonehenge"):
        with pytest.raises(SplatplanError, match="only the apartment"):
            build_builtin(name, haze=True)


def test_cli_writes_the_hazy_apartment(tmp_path, capsys):
    from splatplan.cli import main
    from splatplan.scenes.load import load_scene

    out = tmp_path / "apt.ply"
    assert main(["scene", "apartment", "--haze", "--out", str(out)]) == 0
    s = load_scene(out, filter_floaters=False)
    assert 0.06 <= (s.opacities < 0.1).mean() <= 0.09
    assert "capture_look" in (tmp_path / "apt.gt.json").read_text()
    capsys.readouterr()
    assert main(["scene", "align", str(out), "--haze", "--out", str(tmp_path / "b.ply")]) == 2
    assert "--haze is an option of the built-in apartment" in capsys.readouterr().err
