"""Exact cylinders and spheres in AnalyticScene: SDF vs the single-primitive references, ellipsoid
clearance vs dense sampling of the solid ellipsoid, JSON round trip, bounds, splats on their
surfaces, and the box-only splats unchanged (bit for bit) by the generalisation."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes.builtin import build_builtin
from splatplan.scenes.builtin.primitives import (
    AnalyticScene,
    box_sdf,
    cylinder_sdf,
    make_box,
    make_cylinder,
    make_sphere,
    sphere_sdf,
    splats_from_boxes,
    splats_from_scene,
)
from splatplan.scenes.splats import quat_to_rotmat


def _quats(rng, n):
    q = rng.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _random_scene(rng, n_box=2, n_cyl=3, n_sph=2) -> AnalyticScene:
    boxes = [make_box(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.15, 3), q) for q in _quats(rng, n_box)]
    cyls = [make_cylinder(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.01, 0.1), rng.uniform(0.02, 0.2), q) for q in _quats(rng, n_cyl)]
    sphs = [make_sphere(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.01, 0.1)) for _ in range(n_sph)]
    return AnalyticScene(np.array(boxes).reshape(-1, 10), [], {}, np.array(cyls).reshape(-1, 9), np.array(sphs).reshape(-1, 4))


def _cylinder_sdf_sampled(p, cyl, n=8000):
    """Brute-force |SDF| of one cylinder: distance to dense surface samples (outside only)."""
    rng = np.random.default_rng(1)
    r, h = cyl[3], cyl[4]
    th = rng.uniform(0, 2 * np.pi, n)
    side = np.stack([r * np.cos(th), r * np.sin(th), rng.uniform(-h, h, n)], 1)
    rr = r * np.sqrt(rng.random(n))
    cap = np.stack([rr * np.cos(th), rr * np.sin(th), np.where(rng.random(n) < 0.5, h, -h)], 1)
    surf = np.concatenate([side, cap]) @ quat_to_rotmat(cyl[5:9]).T + cyl[:3]
    return np.min(np.linalg.norm(p[:, None, :] - surf[None], axis=2), axis=1)


@pytest.mark.parametrize("seed", range(3))
def test_cylinder_sdf_reference(seed):
    """The reference agrees with brute-force surface distance outside and is negative inside."""
    rng = np.random.default_rng(seed)
    cyl = make_cylinder(rng.uniform(-0.1, 0.1, 3), rng.uniform(0.02, 0.1), rng.uniform(0.02, 0.2), _quats(rng, 1)[0])
    p = rng.uniform(-0.35, 0.35, (200, 3))
    d = cylinder_sdf(p, cyl)
    out = d > 0
    np.testing.assert_allclose(d[out], _cylinder_sdf_sampled(p[out], cyl), atol=6e-3)  # sampled surface: a bit farther
    assert np.all(_cylinder_sdf_sampled(p[out], cyl) >= d[out] - 1e-12)  # never closer than the exact distance
    local = (p - cyl[:3]) @ quat_to_rotmat(cyl[5:9])
    inside = (np.hypot(local[:, 0], local[:, 1]) < cyl[3]) & (np.abs(local[:, 2]) < cyl[4])
    assert np.array_equal(inside, d < 0)


@pytest.mark.parametrize("seed", range(3))
def test_scene_sdf_is_min_of_references(seed):
    rng = np.random.default_rng(seed)
    sc = _random_scene(rng)
    p = rng.uniform(-0.5, 0.5, (6000, 3))  # > 4096: the box broad phase runs too
    ref = np.min(
        [box_sdf(p, b) for b in sc.boxes] + [cylinder_sdf(p, c) for c in sc.cylinders] + [sphere_sdf(p, s) for s in sc.spheres], axis=0
    )
    np.testing.assert_allclose(sc.sdf(p), ref, atol=1e-12)


def _sampled_clearance(sc, c, q, a, n=6000, seed=0):
    """min of the scene SDF over dense samples of each solid ellipsoid (surface + interior): an
    upper bound on the true clearance."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u = np.concatenate([u, u * rng.random((n, 1)) ** (1 / 3)])
    rot = quat_to_rotmat(q).reshape(-1, 3, 3)
    return np.array([sc.sdf(c[i] + (u * a[i]) @ rot[i].T).min() for i in range(len(c))])


@pytest.mark.parametrize("kind", ["cylinder", "sphere"])
def test_ellipsoid_clearance_vs_sampling(kind):
    """Positive values (separated): never above the sampled minimum (which is >= the true value)
    beyond rounding, certified by the separating-plane lower bound. Negative values (penetrating):
    the depth of a feasible point, so at most 0.2 mm shallower than the sampled one. Close to the
    sampled minimum everywhere; the sign agrees with it."""
    rng = np.random.default_rng(7)
    sc = _random_scene(rng, 0, 3, 0) if kind == "cylinder" else _random_scene(rng, 0, 0, 3)
    n = 120
    c = rng.uniform(-0.4, 0.4, (n, 3))
    q = _quats(rng, n)
    a = rng.uniform(0.005, 0.12, (n, 3))
    val, lo, hi = sc.ellipsoid_clearance(c, q, a, return_bounds=True)
    smp = _sampled_clearance(sc, c, q, a)
    pos = val > 1e-6
    assert np.all(val[pos] <= smp[pos] + 1e-7), (val - smp)[pos].max()
    assert np.all(val[~pos] <= smp[~pos] + 2e-4), (val - smp)[~pos].max()
    assert np.all(val >= smp - 3e-3)  # the samples are 6000 per ellipsoid: within a few mm of the optimum
    assert np.all(lo <= val + 1e-12) and np.all(val <= hi + 1e-12)
    assert np.all(hi[pos] - lo[pos] < 1e-5)  # alternating projections converge slowly near contact
    assert np.array_equal(val < 0, smp < 0) or np.all(np.abs(smp[(val < 0) != (smp < 0)]) < 3e-3)


def test_sphere_clearance_closed_form():
    """A sphere ball vs a sphere primitive: |c1 - c2| - r1 - r2 exactly."""
    rng = np.random.default_rng(3)
    sph = make_sphere([0.1, -0.2, 0.3], 0.05)
    sc = AnalyticScene(np.zeros((0, 10)), spheres=sph[None])
    c = rng.uniform(-0.5, 0.5, (200, 3))
    r = rng.uniform(0.01, 0.2, 200)
    val = sc.ellipsoid_clearance(c, None, np.repeat(r[:, None], 3, 1))
    ref = np.maximum(np.linalg.norm(c - sph[:3], axis=1) - r, 0.0) - 0.05
    np.testing.assert_allclose(val, ref, atol=1e-9)


def test_json_roundtrip_bounds_select_and_v1(tmp_path):
    rng = np.random.default_rng(4)
    sc = _random_scene(rng)
    sc.labels[-1] = "ball"
    path = sc.save(tmp_path / "x.gt.json")
    back = AnalyticScene.load(path)
    for k in ("boxes", "cylinders", "spheres"):
        np.testing.assert_allclose(getattr(back, k), getattr(sc, k), rtol=0, atol=1e-15)  # quaternions re-normalised
    assert back.labels == sc.labels and json.loads(path.read_text())["version"] == 2
    # a box-only scene is written as version 1, and version-1 files load
    v1 = AnalyticScene(sc.boxes, ["a", "b"]).to_json()
    assert v1["version"] == 1 and "cylinders" not in v1
    assert len(AnalyticScene.from_json(v1)) == 2
    # bounds contain dense samples of every primitive's surface
    s = splats_from_scene(sc, 20000, seed=0)
    lo, hi = sc.bounds()
    m = s.means[: len(s) - s.info["n_floaters"]]
    assert np.all(m >= lo - 0.01) and np.all(m <= hi + 0.01)
    sub = sc.select(np.array(sc.kinds) != "box")
    assert len(sub.boxes) == 0 and len(sub.cylinders) == 3 and sub.labels[-1] == "ball"
    with pytest.raises(SplatplanError):
        AnalyticScene(np.zeros((0, 10)), cylinders=np.array([[0, 0, 0, -1.0, 1, 1, 0, 0, 0]]))


def test_splats_on_curved_surfaces():
    """Splats hug the exposed surfaces, flat along the normal; buried parts get none."""
    can = make_cylinder([0.0, 0.0, 0.06], 0.03, 0.06)
    table = make_box([0.0, 0.0, -0.02], [0.3, 0.3, 0.02])
    ball = make_sphere([0.15, 0.0, 0.05], 0.05)
    sc = AnalyticScene(table[None], [], {}, can[None], ball[None])
    s = splats_from_scene(sc, 30000, seed=2)
    assert len(s) == 30000
    surf = slice(0, len(s) - s.info["n_floaters"])
    m = s.means[surf]
    spacing = s.info["base_spacing"]
    assert np.percentile(np.abs(sc.sdf(m)), 99) < spacing  # on the surfaces (normal noise 0.15 h)
    # the third axis (smallest std) is the surface normal
    rot = quat_to_rotmat(s.quats[surf])
    g = sc.sdf_gradient(m[:2000])
    cosang = np.abs(np.einsum("pi,pi->p", rot[:2000, :, 2], g))
    assert np.median(cosang) > 0.97
    assert np.all(s.scales[surf, 2] <= s.scales[surf, :2].min(axis=1))
    # the can stands on the table: nothing sampled inside the table top or the can
    assert np.mean(sc.sdf(m) < -0.5 * spacing) < 0.01
    # a cap's share is its share of the area (stratified sampling)
    on_ball = np.abs(np.linalg.norm(m - ball[:3], axis=1) - 0.05) < 0.5 * spacing
    ball_area = 4 * np.pi * 0.05**2
    total = 2 * 0.6 * 0.6 + 4 * 0.6 * 0.04 + 2 * np.pi * 0.03 * 0.12 + np.pi * 0.03**2 + ball_area  # exposed, roughly
    assert 0.5 < on_ball.mean() / (ball_area / total) < 1.5


def _digest(s) -> str:
    h = hashlib.sha256()
    for a in (s.means, s.quats, s.scales, s.opacities, s.colors):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


#: sha256 prefixes of the built-in scenes' splats (seed 3, 20k splats), recorded with the box-only
#: sampler before cylinders and spheres were added (numpy on x86-64 Linux).
BOX_ONLY_DIGESTS = {"tabletop": "4fed545bc8b2a5f6", "apartment": "96dc560bece88a4a", "stonehenge": "f3c5197cd19ac339"}


@pytest.mark.parametrize("name", sorted(BOX_ONLY_DIGESTS))
def test_box_scenes_unchanged(name):
    s, _ = build_builtin(name, seed=3, n_splats=20000)
    assert _digest(s) == BOX_ONLY_DIGESTS[name]
    assert splats_from_boxes is splats_from_scene


@pytest.mark.parametrize("depth", [1e-4, 1e-3])
def test_shallow_penetration_is_negative(depth):
    """An ellipsoid tip cutting a cylinder's side (or a box face) by a tiny depth: no sample of the
    ellipsoid is inside, alternating projections creep towards the intersection without a separating
    plane, and the result must still be negative (the depth ascent runs when no certificate exists)."""
    a = np.array([0.06, 0.02, 0.05])
    cyl = AnalyticScene(np.zeros((0, 10)), cylinders=make_cylinder([0, 0, 0], 0.03, 0.1)[None])
    box = AnalyticScene(make_box([0, 0, 0], [0.03, 0.1, 0.1])[None])
    rot = np.array([np.cos(0.35), 0, np.sin(0.35), 0])  # 40 deg about y: the deepest point stays at y = 0
    for sc in (cyl, box):
        # place the ellipsoid so that its support along -x reaches depth `depth` into x < 0.03
        r = quat_to_rotmat(rot)
        support = np.linalg.norm(r.T @ np.array([1.0, 0, 0]) * a)
        c = np.array([0.03 + support - depth, 0.0, 0.0])
        val, lo, hi = sc.ellipsoid_clearance(c, rot, a, return_bounds=True)
        assert val < 0 and val == pytest.approx(-depth, abs=0.3 * depth + 2e-5), val
        val_out = sc.ellipsoid_clearance(c + [2 * depth, 0, 0], rot, a)
        assert val_out == pytest.approx(depth, abs=1e-6)


def _scene_scaled(k: float) -> AnalyticScene:
    """A table with a can and a ball on it, every length times k."""
    boxes = [make_box((0, 0, 0.4 * k), (0.5 * k, 0.3 * k, 0.02 * k)), make_box((0.3 * k, 0, 0.2 * k), (0.02 * k, 0.02 * k, 0.2 * k))]
    cyl = make_cylinder((0, 0, 0.47 * k), 0.03 * k, 0.05 * k)
    sph = make_sphere((-0.2 * k, 0.1 * k, 0.46 * k), 0.04 * k)
    return AnalyticScene(np.array(boxes), [], {}, cyl[None], sph[None])


def test_splat_count_per_area_keeps_the_spacing():
    """n_splats_for_spacing: the sampler's grid comes out just under the asked spacing, on a small
    scene and on the same scene twice as large (which gets ~4x the splats)."""
    from splatplan.scenes.builtin.primitives import n_splats_for_spacing

    counts = []
    for k in (1.0, 2.0):
        sc = _scene_scaled(k)
        n = n_splats_for_spacing(sc, 0.01)
        h = splats_from_scene(sc, n, seed=1).info["base_spacing"]
        assert 0.9 * 0.01 <= h <= 0.01, (k, n, h)
        counts.append(n)
    assert 3.6 < counts[1] / counts[0] < 4.4
    with pytest.raises(SplatplanError, match="spacing"):
        n_splats_for_spacing(_scene_scaled(1.0), float("nan"))


def test_min_ellipsoid_clearance_is_the_minimum_of_the_full_evaluation():
    """min_ellipsoid_clearance (only the pairs that can hold the minimum solved) equals
    ellipsoid_clearance(...).min() on boxes, cylinders and spheres, for batches whose minimum is
    positive (separated) and negative (penetrating), in small chunks too; +inf for no ellipsoid."""
    rng = np.random.default_rng(11)
    signs = []
    for trial in range(6):
        sc = _random_scene(rng, 2, 2, 2)
        n = 200
        c = rng.uniform(-0.6, 0.6, (n, 3))
        if trial % 2 == 0:  # keep every centre clear of the primitives (a positive minimum, most pairs far)
            c = c[sc.sdf(c) > 0.13][:60]
        q = _quats(rng, len(c))
        a = rng.uniform(0.005, 0.12, (len(c), 3))
        full = float(sc.ellipsoid_clearance(c, q, a).min())
        assert sc.min_ellipsoid_clearance(c, q, a) == full
        assert sc.min_ellipsoid_clearance(c, q, a, chunk=7) == full
        signs.append(full > 0)
    assert signs[0::2] == [True] * 3 and not any(signs[1::2])  # both cases met
    assert sc.min_ellipsoid_clearance(np.zeros((0, 3)), None, np.ones(3)) == float("inf")
