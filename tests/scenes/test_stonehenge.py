"""The analytic primitives (exact SDF) and the built-in Stonehenge scene."""

from __future__ import annotations

import json

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.robots import point_radius
from splatplan.scenes.builtin.primitives import AnalyticScene, SurfaceSplatConfig, sample_faces, box_sdf, make_box, splats_from_boxes
from splatplan.scenes.splats import quat_to_rotmat, rotmat_to_quat
from splatplan.scenes.builtin.stonehenge import (
    PLANE_Z,
    RING_GATES,
    box_cross_section,
    build_stonehenge,
    default_n_splats,
    level_config,
    ground_truth_path,
    load_ground_truth,
    plot_top_view,
    stonehenge_layout,
    write_stonehenge,
)

N_SMALL = 30_000  # splat count for the quick checks


@pytest.fixture(scope="module")
def layout():
    return stonehenge_layout(0)


@pytest.fixture(scope="module")
def small():
    return build_stonehenge(level=1, seed=0, n_splats=N_SMALL)


def _random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# ------------------------------------------------------------------------------ exact SDF


def test_box_sdf_known_distances_axis_aligned():
    box = make_box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0))
    pts = np.array(
        [
            [1.5, 0.0, 0.0],  # face, 0.5 out
            [1.5, 2.5, 0.0],  # edge
            [2.0, 3.0, 4.0],  # corner
            [0.0, 0.0, 0.0],  # centre: depth 1 (nearest face x)
            [0.9, 0.0, 0.0],  # inside near a face
            [-1.0, 1.0, 2.0],  # on a face
        ]
    )
    want = [0.5, np.sqrt(0.5), np.sqrt(3.0), -1.0, -0.1, 0.0]
    np.testing.assert_allclose(box_sdf(pts, box), want, atol=1e-12)
    np.testing.assert_allclose(AnalyticScene(box[None]).sdf(pts), want, atol=1e-12)


def test_box_sdf_known_distances_rotated():
    rng = np.random.default_rng(3)
    q = _random_rotations(rng, 1)[0]
    c = np.array([0.3, -0.2, 0.5])
    h = np.array([0.1, 0.2, 0.05])
    box = make_box(c, h, q)
    r = quat_to_rotmat(q)
    local = np.array([[0.1 + 0.07, 0.0, 0.0], [0.13, 0.24, 0.0], [-0.11, -0.22, -0.07], [0.0, 0.0, 0.01], [0.05, -0.2, 0.0]])
    want = [0.07, 0.05, np.sqrt(0.01**2 + 0.02**2 + 0.02**2), -0.04, 0.0]
    pts = local @ r.T + c
    np.testing.assert_allclose(AnalyticScene(box[None]).sdf(pts), want, atol=1e-12)
    # the quaternion is wxyz: reading it as xyzw gives a different box
    wrong = make_box(c, h, np.roll(q, -1))
    assert np.abs(AnalyticScene(wrong[None]).sdf(pts) - want).max() > 1e-3


def test_union_sdf_matches_bruteforce_per_box(layout):
    scene = layout.scene
    rng = np.random.default_rng(0)
    lo, hi = scene.bounds()
    pts = rng.uniform(lo - 0.05, hi + 0.05, (6000, 3))
    pts[:3000, 2] = rng.uniform(-0.01, 0.2, 3000)  # dense near the stones
    ref = np.min([box_sdf(pts, b) for b in scene.boxes], axis=0)
    np.testing.assert_allclose(scene.sdf(pts), ref, atol=1e-12)  # with the broad phase
    np.testing.assert_allclose(scene.sdf(pts, broad_phase=False), ref, atol=1e-12)
    np.testing.assert_allclose(scene.sdf(pts[:500], chunk=7), ref[:500], atol=1e-12)  # chunking changes nothing
    assert scene.sdf(np.zeros(3)).shape == (1,)


def test_union_sdf_exact_outside_vs_dense_surface_samples():
    # two overlapping rotated boxes: outside the union, sdf = distance to the exposed surface
    rng = np.random.default_rng(1)
    boxes = np.stack([make_box((0, 0, 0), (0.2, 0.1, 0.1), _random_rotations(rng, 1)[0]), make_box((0.15, 0.05, 0.0), (0.1, 0.15, 0.08), _random_rotations(rng, 1)[0])])
    scene = AnalyticScene(boxes)
    h = 0.004
    surf = sample_faces(scene, np.full(2, h), np.ones((2, 6), bool), rng)["p"]  # exposed surface only
    assert np.all(np.abs(scene.sdf(surf)) < 1e-9)
    pts = rng.uniform(-0.5, 0.5, (400, 3))
    d = scene.sdf(pts)
    pts, d = pts[d > 0.01], d[d > 0.01]
    from scipy.spatial import cKDTree

    nn = cKDTree(surf).query(pts)[0]
    assert np.all(nn >= d - 1e-9)  # never farther than the true surface
    assert np.all(nn <= d + h)  # and the nearest sample is within one spacing of it


def test_union_sdf_inside_is_negative_and_bounded():
    # inside the union the min of box distances has the right sign and never overstates the depth
    boxes = np.stack([make_box((0, 0, 0), (0.2, 0.1, 0.1)), make_box((0.3, 0, 0), (0.2, 0.1, 0.1))])
    scene = AnalyticScene(boxes)
    p = np.array([[0.15, 0.0, 0.0]])  # inside both; true depth 0.1 (y/z faces), box0 says -0.05
    assert -0.1 <= scene.sdf(p)[0] < 0


def test_sdf_gradient_unit_and_bounds():
    scene = AnalyticScene(make_box((0, 0, 0), (1, 1, 1))[None])
    g = scene.sdf_gradient(np.array([[2.0, 0.1, 0.2], [0.0, 0.0, 1.5]]))
    np.testing.assert_allclose(g, [[1, 0, 0], [0, 0, 1]], atol=1e-6)
    lo, hi = AnalyticScene(make_box((1, 2, 3), (0.5, 0.5, 0.5), (np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)))[None]).bounds()
    np.testing.assert_allclose(hi - lo, [np.sqrt(2), np.sqrt(2), 1.0], atol=1e-12)


def test_analytic_scene_rejects_bad_input():
    with pytest.raises(SplatplanError, match="shape"):
        AnalyticScene(np.zeros((3, 9)))
    with pytest.raises(SplatplanError, match="half-extents"):
        AnalyticScene(np.array([[0, 0, 0, 1, 0, 1, 1, 0, 0, 0.0]]))
    with pytest.raises(SplatplanError):
        AnalyticScene.from_json({"format": "nope"})


def test_analytic_scene_json_roundtrip(layout, tmp_path):
    scene = layout.scene
    back = AnalyticScene.from_json(json.loads(json.dumps(scene.to_json())))
    np.testing.assert_array_equal(back.boxes, scene.boxes)
    assert back.labels == scene.labels and back.meta == scene.meta
    path = scene.save(tmp_path / "s.gt.json")
    np.testing.assert_array_equal(AnalyticScene.load(path).boxes, scene.boxes)


# ------------------------------------------------------------------------------ the layout


def test_layout_bounds_ground_and_plane(layout):
    scene = layout.scene
    lo, hi = scene.bounds()
    assert np.all(lo[:2] >= -0.5 - 1e-12) and np.all(hi[:2] <= 0.5 + 1e-12)
    assert 0.13 < hi[2] < 0.2
    # ground top at z = 0
    assert scene.labels[0] == "ground"
    assert abs(scene.boxes[0, 2] + scene.boxes[0, 5]) < 1e-12
    assert abs(scene.sdf(np.array([0.0, 0.49, 0.01]))[0] - 0.01) < 1e-12
    # the planning plane cuts every upright; the centre is free for the robot
    for box, lab in zip(scene.boxes, scene.labels):
        if lab in ("sarsen", "trilithon", "leaning"):
            assert box_cross_section(box, PLANE_Z) is not None
            assert box[2] + box[5] >= 0.1 if lab != "leaning" else True
    stones = np.arange(1, len(scene))
    assert scene.sdf(np.array([0.0, 0.0, PLANE_Z]), box_ids=stones)[0] > 3 * point_radius()


def test_gate_widths(layout):
    w = layout.gate_widths
    assert len(w) == len(RING_GATES)
    np.testing.assert_allclose(w, [g for g, _ in RING_GATES], atol=0.003)  # seed jitter only
    assert np.sum(w < 2 * point_radius()) >= 3  # too narrow for the robot
    assert np.sum((w > 0.03) & (w < 0.05)) >= 3  # tight
    assert np.sum(w > 0.06) >= 4  # clearly wide
    assert (~layout.gate_has_lintel).sum() >= 2  # gaps in the ring
    # the gate centre is equidistant from the two sarsens: their sdf there = width / 2; in 3D the
    # ground or a lintel may be closer for the wide gates, but nothing is closer for narrow ones
    sarsens = np.flatnonzero(np.array(layout.scene.labels) == "sarsen")
    np.testing.assert_allclose(layout.scene.sdf(layout.gate_centers, box_ids=sarsens), w / 2, atol=1e-9)
    d = layout.scene.sdf(layout.gate_centers)
    assert np.all(d <= w / 2 + 1e-9)
    np.testing.assert_allclose(d[w < 0.06], w[w < 0.06] / 2, atol=1e-9)
    assert 0.25 < layout.ring_radius < 0.4


def test_layout_deterministic_and_seeded():
    a, b, c = stonehenge_layout(0), stonehenge_layout(0), stonehenge_layout(1)
    np.testing.assert_array_equal(a.scene.boxes, b.scene.boxes)
    assert not np.array_equal(a.scene.boxes, c.scene.boxes)
    assert a.scene.labels == c.scene.labels
    a.scene.boxes[:] = 0  # copies: the cache is not poisoned
    assert np.any(stonehenge_layout(0).scene.boxes != 0)


# ------------------------------------------------------------------------------ the splats


def test_splats_lie_on_the_surface(small):
    splats, scene = small
    splats.validate()
    nf = splats.info["n_floaters"]
    assert len(splats) == N_SMALL and nf >= 1
    d = scene.sdf(splats.means[:-nf])
    h = 2 * splats.info["base_spacing"]  # ground spacing (the coarser one)
    noise = 0.2 * h  # largest position-noise std
    assert np.abs(d).max() < 6 * noise
    assert np.median(np.abs(d)) < 0.5 * noise
    # floaters float
    assert np.all(scene.sdf(splats.means[-nf:]) > 0.02 - 1e-6)


def test_floater_rule_removes_most_floaters_and_no_surface_splats():
    splats, _ = build_stonehenge(level=1, seed=0)
    nf = splats.info["n_floaters"]
    assert nf == pytest.approx(0.0005 * len(splats), abs=1)
    ms = splats.scales.max(axis=1)
    drop = (splats.opacities < 0.1) & (ms > 5 * np.median(ms))
    assert not drop[:-nf].any()
    assert drop[-nf:].mean() > 0.7
    o = splats.opacities[:-nf]
    assert np.mean(o >= 0.6) > 0.8 and o.min() > 0.1


def test_splats_are_flat_along_the_surface_normal(small):
    splats, scene = small
    nf = splats.info["n_floaters"]
    np.testing.assert_allclose(np.linalg.norm(splats.quats, axis=1), 1.0, atol=1e-6)
    s = splats.scales[:-nf]
    assert np.all(s[:, 2] < s[:, :2].min(axis=1))  # third axis is the thinnest
    ratio = s[:, 2] / s[:, :2].min(axis=1)  # thickness is relative to the smaller tangential std
    assert 0.08 < np.median(ratio) < 0.25
    idx = np.random.default_rng(0).choice(len(s), 3000, replace=False)
    normal = splats.rotations()[idx, :, 2]  # (n, 3) local z axis in world, wxyz quats
    grad = scene.sdf_gradient(splats.means[idx].astype(np.float64), eps=1e-5)
    dot = np.abs(np.einsum("ni,ni->n", normal, grad))
    # normals are tilted off the face normal by a Rayleigh angle of scale tilt_deg: median 1.177 x
    tilt = level_config(1).tilt_deg
    median_angle = np.degrees(np.arccos(np.clip(np.median(dot), -1, 1)))
    assert 0.85 * 1.177 * tilt < median_angle < 1.15 * 1.177 * tilt
    assert np.mean(dot > np.cos(np.radians(4 * tilt))) > 0.9  # the rest sit near edges where the gradient turns


def test_untilted_splats_are_aligned_with_the_face_normal():
    q = rotmat_to_quat(quat_to_rotmat(np.array([0.9, 0.1, -0.3, 0.2])))
    scene = AnalyticScene(make_box((0.1, 0.2, 0.3), (0.1, 0.05, 0.08), q)[None])
    splats = splats_from_boxes(scene, 3000, config=SurfaceSplatConfig(tilt_deg=0.0, floater_fraction=0.0), seed=0)
    normal = splats.rotations()[:, :, 2]
    grad = scene.sdf_gradient(splats.means.astype(np.float64), eps=1e-5)
    dot = np.abs(np.einsum("ni,ni->n", normal, grad))
    assert np.median(dot) > 0.999
    assert np.mean(dot > 0.95) > 0.9


def test_splats_deterministic_and_cache_returns_copies():
    a, _ = build_stonehenge(level=3, seed=0, n_splats=5000)
    b, _ = build_stonehenge(level=3, seed=0, n_splats=5000)
    c, _ = build_stonehenge(level=3, seed=1, n_splats=5000)
    for f in ("means", "quats", "scales", "opacities", "colors"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert not np.array_equal(a.means, c.means)
    a.means[:] = 0
    assert np.any(build_stonehenge(level=3, seed=0, n_splats=5000)[0].means != 0)


def test_levels_fewer_and_larger_splats():
    counts, sizes, thick = [], [], []
    for level in range(1, 6):
        n = default_n_splats(level) // 10
        splats, _ = build_stonehenge(level=level, seed=0, n_splats=n)
        assert len(splats) == n
        counts.append(n)
        sizes.append(float(np.median(splats.scales.max(axis=1))))
        thick.append(float(np.median(splats.scales[:, 2] / splats.scales[:, :2].mean(axis=1))))
    assert default_n_splats(1) == 200_000
    assert all(x > y for x, y in zip(counts, counts[1:]))
    assert all(x < y for x, y in zip(sizes, sizes[1:]))
    assert all(x < y for x, y in zip(thick, thick[1:]))
    with pytest.raises(SplatplanError, match="level"):
        build_stonehenge(level=6)


def test_splats_from_boxes_generic_single_box():
    q = rotmat_to_quat(quat_to_rotmat(np.array([0.9, 0.1, -0.3, 0.2])))
    scene = AnalyticScene(make_box((0.1, 0.2, 0.3), (0.1, 0.05, 0.08), q)[None])
    splats = splats_from_boxes(scene, 2000, seed=0)
    assert len(splats) == 2000
    # every face is covered (area-weighted)
    nf = splats.info["n_floaters"]
    local = (splats.means[: len(splats) - nf] - scene.boxes[0, :3]) @ quat_to_rotmat(q)  # (S, 3) box frame
    axis = np.argmax(np.abs(local) / scene.boxes[0, 3:6], axis=1)
    face = 2 * axis + (local[np.arange(len(local)), axis] < 0)  # FACE_NAMES order
    counts = np.bincount(face, minlength=6)
    h = scene.boxes[0, 3:6]
    area = 4 * np.repeat([h[1] * h[2], h[0] * h[2], h[0] * h[1]], 2)
    np.testing.assert_allclose(counts / counts.sum(), area / area.sum(), atol=0.03)


# ------------------------------------------------------------------------------ files and plots


def test_write_stonehenge_roundtrip(tmp_path):
    ply, gt = write_stonehenge(tmp_path / "sh5.ply", level=5, seed=0)
    assert gt == ground_truth_path(ply) == tmp_path / "sh5.gt.json"
    splats, scene = build_stonehenge(level=5, seed=0)
    back = load_ground_truth(ply)
    np.testing.assert_array_equal(back.boxes, scene.boxes)
    assert back.meta["level"] == 5 and back.meta["n_splats"] == len(splats)
    load = pytest.importorskip("splatplan.scenes.load")
    read = load.load_scene(ply, filter_floaters=False)
    assert len(read) == len(splats)
    np.testing.assert_allclose(read.means, splats.means, atol=1e-7)
    np.testing.assert_allclose(read.scales, splats.scales, rtol=1e-5)
    np.testing.assert_allclose(read.opacities, splats.opacities, atol=1e-5)
    np.testing.assert_allclose(np.abs(np.einsum("ni,ni->n", read.quats, splats.quats)), 1.0, atol=1e-5)
    filtered = load.load_scene(ply)  # the default floater rule drops most floaters only
    assert len(splats) - splats.info["n_floaters"] <= len(filtered) < len(splats)
    with pytest.raises(SplatplanError):
        write_stonehenge(tmp_path / "x.splat")


def test_plot_top_view_smoke(layout):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    plot_top_view(ax, layout.scene, PLANE_Z, inflate=point_radius())
    n_sections = sum(box_cross_section(b, PLANE_Z) is not None for b in layout.scene.boxes)
    assert len(ax.patches) >= n_sections
    plt.close(fig)


def test_gates_are_designed_for_the_studies_sphere(layout):
    """The scene stage does not import the robot stage: the sphere the gates are sized for is a
    constant of the scene, and it is the studies' default sphere robot."""
    from splatplan.scenes.builtin.stonehenge import DESIGN_ROBOT_RADIUS

    assert DESIGN_ROBOT_RADIUS == point_radius()
    assert layout.robot_radius == point_radius() == layout.scene.meta["robot_radius"]


def test_levels_are_importable_from_their_old_home():
    from splatplan.scenes.builtin import levels, stonehenge

    assert stonehenge.level_config is levels.level_config and stonehenge.default_n_splats is levels.default_n_splats
    assert stonehenge.N_SPLATS_LEVEL1 == levels.N_SPLATS_LEVEL1 and stonehenge.LEVEL_RATIO == levels.LEVEL_RATIO
    assert [levels.default_n_splats(lv) for lv in levels.LEVELS] == [default_n_splats(lv) for lv in (1, 2, 3, 4, 5)]
    with pytest.raises(SplatplanError):
        levels.splat_count(0, 10)
    assert levels.splat_count(None, 10) == 10
