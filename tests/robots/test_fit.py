"""Ellipsoid fitting: containment guarantees, primitives, shipped YAML, YAML round trip."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splatplan.robots.fit import EllipsoidSet, fit_link, link_points, load_yaml, mahalanobis, mvee, save_yaml, split_fit
from splatplan.robots.urdf import Geom


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.integers(4, 300), st.sampled_from(["blob", "flat", "line", "few"]))
def test_mvee_contains_every_point(seed, n, kind):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * rng.uniform(0.01, 1.0, 3)
    if kind == "flat":
        pts[:, 2] = 0.3
    elif kind == "line":
        pts = np.outer(rng.normal(size=n), [1.0, 2.0, -0.5])
    elif kind == "few":
        pts = pts[:2]
    c, r, s = mvee(pts)
    assert np.all(s > 0) and np.linalg.det(r) == pytest.approx(1.0)
    assert mahalanobis(pts, c, r, s).max() <= 1.0


def test_mvee_of_box_corners_is_the_known_optimum():
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-2, 2) for z in (-3, 3)], dtype=float)
    c, r, s = mvee(corners)
    np.testing.assert_allclose(np.sort(s), math.sqrt(3) * np.array([1, 2, 3]), rtol=2e-3)
    np.testing.assert_allclose(c, 0, atol=1e-9)


def _surface_samples(g: Geom, n=4000, seed=0) -> np.ndarray:
    """Points on the surface of a primitive (geometry frame -> link frame)."""
    rng = np.random.default_rng(seed)
    if g.kind == "sphere":
        p = rng.normal(size=(n, 3))
        p = g.size[0] * p / np.linalg.norm(p, axis=1, keepdims=True)
    elif g.kind == "box":
        p = rng.uniform(-0.5, 0.5, (n, 3)) * g.size
        ax = rng.integers(0, 3, n)
        p[np.arange(n), ax] = np.sign(rng.uniform(-1, 1, n)) * g.size[ax] / 2
    else:  # cylinder / capsule: rim circles and the caps' surfaces
        r, half = g.size[0], g.size[1] / 2
        phi = rng.uniform(0, 2 * np.pi, n)
        if g.kind == "cylinder":
            z = rng.choice([-half, half], n)
            p = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
        else:
            th = rng.uniform(0, np.pi / 2, n)
            sgn = rng.choice([-1.0, 1.0], n)
            p = np.stack([r * np.cos(th) * np.cos(phi), r * np.cos(th) * np.sin(phi), sgn * (half + r * np.sin(th))], 1)
    return p @ g.origin[:3, :3].T + g.origin[:3, 3]


@pytest.mark.parametrize("kind,size", [("sphere", [0.05]), ("cylinder", [0.04, 0.3]), ("capsule", [0.03, 0.15]), ("capsule", [0.05, 0.01]), ("box", [0.3, 0.2, 0.1])])
def test_primitives_are_enclosed(kind, size):
    origin = np.eye(4)
    origin[:3, :3] = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))[0] * [1, 1, -1 if kind == "box" else 1]
    if np.linalg.det(origin[:3, :3]) < 0:
        origin[:3, 0] *= -1
    origin[:3, 3] = [0.1, -0.2, 0.3]
    g = Geom(kind, origin, np.asarray(size, dtype=float))
    (ells, vol) = fit_link("l", [g], 1)
    (c, r, s), = ells
    assert mahalanobis(_surface_samples(g), c, r, s).max() <= 1.0
    assert vol > 0


def test_split_fit_contains_whole_triangles():
    import trimesh

    m = trimesh.creation.capsule(height=0.4, radius=0.05, count=[10, 10])
    m.apply_transform(trimesh.transformations.rotation_matrix(0.9, [1, 0.3, 0.2]))
    for k in (1, 2, 3):
        ells = split_fit(np.asarray(m.vertices), np.asarray(m.edges_unique), k)
        assert len(ells) == k
        pts, _ = trimesh.sample.sample_surface(m, 5000, seed=1)
        inside = np.zeros(len(pts), dtype=bool)
        for c, r, s in ells:
            inside |= mahalanobis(pts, c, r, s) <= 1.0
        assert inside.all(), k


@pytest.mark.parametrize("name", ["panda", "go2"])
def test_shipped_yaml_contains_every_collision_vertex(name):
    """The cached ellipsoids in robots/data/*.yaml still contain every mesh vertex / box corner."""
    from splatplan.robots.builtin import DATA, builtin_urdf
    from splatplan.robots.urdf import read_urdf

    model = read_urdf(builtin_urdf(name)[0])
    ells = load_yaml(DATA / f"{name}.yaml", model.kin.link_names)
    with_geometry = [l for l in model.kin.link_names if model.collisions[l]]
    assert sorted(set(ells.link)) == sorted(with_geometry)
    for link in with_geometry:
        pts = link_points(model.collisions[link], link)
        idx = [i for i, l in enumerate(ells.link) if l == link]
        inside = np.zeros(len(pts), dtype=bool)
        for i in idx:
            inside |= mahalanobis(pts, ells.center[i], ells.rot[i], ells.semi_axes[i]) <= 1.0
        assert inside.all(), link


def test_yaml_round_trip(tmp_path, tree_robot):
    from splatplan.robots import load_robot

    rng = np.random.default_rng(0)
    rots = np.linalg.qr(rng.normal(size=(3, 3, 3)))[0]
    rots[np.linalg.det(rots) < 0, :, 0] *= -1
    e = EllipsoidSet(["a", "b", "b"], rng.normal(size=(3, 3)), rots, rng.uniform(0.01, 0.2, (3, 3)), {"a": {"volume_ratio": 1.5}}, ["c"])
    save_yaml(e, tmp_path / "e.yaml", robot="x")
    back = load_yaml(tmp_path / "e.yaml")
    assert back.link == e.link and back.skipped == ["c"]
    np.testing.assert_allclose(back.center, e.center, atol=0)
    np.testing.assert_allclose(back.semi_axes, e.semi_axes, atol=0)
    np.testing.assert_allclose(back.rot, e.rot, atol=1e-12)
    # a robot's own ellipsoids survive save -> load_robot(ellipsoids=...)
    src = EllipsoidSet([tree_robot.link_names[l] for l in tree_robot.ellipsoid_link], tree_robot.ellipsoid_local[:, :3, 3],
                       tree_robot.ellipsoid_local[:, :3, :3], tree_robot.semi_axes, tree_robot.fit_report)  # fmt: skip
    save_yaml(src, tmp_path / "t.yaml")
    r2 = load_robot(tree_robot.info["urdf"], ellipsoids=tmp_path / "t.yaml")
    q = np.full(tree_robot.dof, 0.3)
    np.testing.assert_allclose(r2.ellipsoid_frames(q)[0], tree_robot.ellipsoid_frames(q)[0], atol=1e-12)


def test_bad_yaml(tmp_path):
    from splatplan.errors import SplatplanError

    p = tmp_path / "bad.yaml"
    for text, msg in [("ellipsoids: [", "not valid YAML"), ("foo: 1", "non-empty list"),
                      ("ellipsoids:\n- {link: a, center: [0, 0], semi_axes: [1, 1, 1]}", "entry 0"),
                      ("ellipsoids:\n- {link: a, center: [0, 0, 0], semi_axes: [1, -1, 1]}", "semi-axes <= 0")]:  # fmt: skip
        p.write_text(text)
        with pytest.raises(SplatplanError, match=msg):
            load_yaml(p)
    p.write_text("ellipsoids:\n- {link: nope, center: [0, 0, 0], semi_axes: [1, 1, 1]}")
    with pytest.raises(SplatplanError, match="does not have"):
        load_yaml(p, ["a"])
