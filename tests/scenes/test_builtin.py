"""Built-in scenes: registry, splats on the exact geometry, ellipsoid clearance vs brute force."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes.builtin import BUILTIN_SCENES, build_builtin, write_builtin
from splatplan.scenes.builtin.apartment import DOORS, apartment_layout, room_of
from splatplan.scenes.builtin.primitives import AnalyticScene, fibonacci_sphere, make_box
from splatplan.scenes.builtin.tabletop import TABLE_TOP
from splatplan.scenes.splats import quat_to_rotmat


def test_registry_names():
    assert set(BUILTIN_SCENES) == {"stonehenge", "tabletop", "apartment"}
    with pytest.raises(SplatplanError, match="available"):
        build_builtin("nowhere")


@pytest.mark.parametrize("name", ["tabletop", "apartment"])
def test_splats_lie_on_the_zero_level_set(name):
    splats, gt = build_builtin(name, n_splats=20_000)
    n_surf = len(splats) - splats.info["n_floaters"]
    d = gt.sdf(splats.means[:n_surf].astype(np.float64))
    h = splats.info["base_spacing"] * 3  # walls/legs use up to 3x the base spacing
    assert np.quantile(np.abs(d), 0.99) < h, (name, np.quantile(np.abs(d), 0.99), h)
    assert np.all(np.isfinite(splats.colors)) and splats.colors.min() >= 0 and splats.colors.max() <= 1
    # floaters float in free space
    assert np.all(gt.sdf(splats.means[n_surf:].astype(np.float64)) > 0.0)
    # distinct object colours
    objects = [i for i, lab in enumerate(gt.labels) if lab.startswith("object_")]
    assert len(objects) >= 5


def test_builds_are_deterministic_copies():
    a, ga = build_builtin("tabletop", n_splats=5000, seed=3)
    a.means[:] = 0
    b, gb = build_builtin("tabletop", n_splats=5000, seed=3)
    assert np.any(b.means != 0)
    np.testing.assert_array_equal(ga.boxes, gb.boxes)


def test_apartment_doors_and_rooms():
    lay = apartment_layout()
    widths = sorted(d["width"] for d in lay.doors.values())
    assert widths[0] < 0.31 < widths[-1]  # one narrower than the Go2, others wider
    lo, hi = lay.scene.bounds()
    assert 7.5 < hi[0] - lo[0] < 9 and 5.5 < hi[1] - lo[1] < 7
    for name, ax, c, s, e, rooms in DOORS:
        mid = (s + e) / 2
        p = np.array([[c, mid, 0.3]]) if ax == "x" else np.array([[mid, c, 0.3]])
        assert lay.scene.sdf(p)[0] >= min((e - s) / 2, 0.3) - 1e-9  # the doorway is open
    assert room_of((-2, 0)) == "living" and room_of((2, 2)) == "bedroom" and room_of((2, -2)) == "kitchen"


def test_write_builtin_roundtrip(tmp_path):
    from splatplan.scenes.load import load_scene
    from splatplan.scenes.builtin.stonehenge import load_ground_truth

    ply, gt = write_builtin("apartment", tmp_path / "apt.ply")
    s = load_scene(ply, filter_floaters=False)
    assert len(s) == 160_000
    g = load_ground_truth(ply)
    assert g.meta["name"] == "apartment" and len(g) > 20


def _brute_force(scene: AnalyticScene, c, q, a, n=6000):
    u = np.concatenate([fibonacci_sphere(n) * s for s in (1.0, 0.8, 0.6, 0.4, 0.2)] + [np.zeros((1, 3))])
    r = quat_to_rotmat(q).reshape(-1, 3, 3)
    return np.array([scene.sdf(c[i] + (u * a[i]) @ r[i].T).min() for i in range(len(c))])


def test_ellipsoid_clearance_vs_brute_force():
    rng = np.random.default_rng(0)
    boxes = [make_box((0, 0, 0), (0.3, 0.2, 0.02)), make_box((0.2, 0.1, 0.2), (0.05, 0.1, 0.15), (0.9, 0.1, 0.3, 0.2))]
    scene = AnalyticScene(np.stack(boxes))
    n = 40
    c = rng.uniform([-0.4, -0.3, -0.1], [0.4, 0.3, 0.4], (n, 3))
    q = rng.standard_normal((n, 4))
    a = rng.uniform(0.01, 0.08, (n, 3))
    v, lo, hi = scene.ellipsoid_clearance(c, q, a, return_bounds=True)
    bf = _brute_force(scene, c, q, a)
    pos = bf > 1e-3
    assert pos.sum() > 5 and (~pos).sum() > 5
    # separated: certified bounds (gap < 1e-6) and the brute force (a sample) can only be larger
    assert np.all(hi[pos] - lo[pos] < 1e-6)
    assert np.all(v[pos] <= bf[pos] + 1e-9) and np.all(bf[pos] - v[pos] < 2e-3 * a[pos].max(1) + 1e-4)
    # penetrating: the deepest point found is within 0.1 mm of the sampled one (or deeper)
    assert np.all(v[~pos] <= bf[~pos] + 1e-4)
    assert np.all(v[~pos] < 1e-9) == np.all(bf[~pos] < 1e-9)
    # a sphere is the SDF minus the radius
    r = 0.03
    vs = scene.ellipsoid_clearance(c, None, np.full(3, r))
    d = scene.sdf(c)
    far = d > r
    np.testing.assert_allclose(vs[far], d[far] - r, atol=1e-8)


def test_ellipsoid_clearance_shapes_and_errors():
    _, gt = build_builtin("tabletop", n_splats=2000)
    c = np.zeros((2, 5, 3)) + [-0.2, 0.0, 0.2]
    out = gt.ellipsoid_clearance(c, np.array([1.0, 0, 0, 0]), np.array([0.05, 0.04, 0.03]))
    assert out.shape == (2, 5)
    np.testing.assert_allclose(out, 0.2 - TABLE_TOP - 0.03, atol=1e-7)  # above the table top, nothing closer
    with pytest.raises(SplatplanError):
        gt.ellipsoid_clearance(np.full((1, 3), np.nan), None, np.ones(3))
