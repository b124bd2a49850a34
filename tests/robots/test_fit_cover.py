"""The tight cover fitter: its containment certificate, the model measurement, the fit cache, and
the built-in Panda's models and finger opening."""

from __future__ import annotations


import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.robots import fit_cover as fc
from splatplan.robots.fit import mvee

from .conftest import MBM, inside_union as _inside, write_tree



def test_simplices_partition_a_star_shaped_solid():
    import trimesh

    box = trimesh.creation.box(extents=[0.2, 0.1, 0.05])
    simp, full = fc.simplices_of(box)
    assert full and simp.shape[1:] == (4, 3)
    a, b, c, d = (simp[:, i] for i in range(4))
    vol = np.abs(np.einsum("ki,ki->k", b - a, np.cross(c - a, d - a))).sum() / 6.0
    assert vol == pytest.approx(0.2 * 0.1 * 0.05, rel=1e-9)
    two = fc._bisect(simp)
    assert two.shape == (2 * len(simp), 4, 3)


def test_certify_grows_the_union_until_it_holds_the_solid():
    """Two balls that leave the box's corners out: after the certificate, random points of the
    solid are all inside (the union provably contains every simplex)."""
    import trimesh

    box = trimesh.creation.box(extents=[0.2, 0.1, 0.1])
    ells = [(np.array([-0.05, 0, 0]), np.eye(3), np.full(3, 0.07)), (np.array([0.05, 0, 0]), np.eye(3), np.full(3, 0.07))]
    pts = np.random.default_rng(0).uniform([-0.1, -0.05, -0.05], [0.1, 0.05, 0.05], size=(20000, 3))
    assert not _inside(pts, ells).all()
    simp, _ = fc.simplices_of(box)
    fixed, stats = fc.certify(ells, simp, max_depth=8)
    assert stats["repairs"] > 0 and stats["max_scale"] > 1.0
    assert _inside(pts, fixed).all()
    corners = np.asarray(box.vertices)
    assert _inside(corners, fixed).all()


def test_fit_link_cover_contains_random_interior_and_surface_points():
    import trimesh

    solid = trimesh.creation.cylinder(radius=0.04, height=0.2, sections=24)
    cfg = fc.FitConfig(n_points=600, n_seeds=6, n_cuts=4, max_per_link=6)
    ells, stats = fc.fit_link_cover([solid], cfg)
    assert stats["certificate"] == "solid" and 1 <= len(ells) <= 6 + stats["repairs"]
    rng = np.random.default_rng(1)
    pts = rng.uniform(solid.bounds[0], solid.bounds[1], size=(20000, 3))
    pts = pts[solid.contains(pts)]
    surf, _ = trimesh.sample.sample_surface(solid, 5000, seed=2)
    assert _inside(pts, ells).all() and _inside(np.asarray(surf), ells).all()
    again, _ = fc.fit_link_cover([solid], cfg)  # deterministic
    assert all(np.array_equal(a[2], b[2]) for a, b in zip(ells, again))


def test_measure_link_of_an_exact_model():
    """A ball measured against an icosphere inscribed in it: full coverage, volume ratio ~ 1, reach
    ~ the gap between the ball and the polyhedron."""
    import trimesh

    from splatplan.robots.fit_measure import measure_link

    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    m = measure_link([(np.zeros(3), np.eye(3), np.full(3, 0.05))], [ball], n_samples=4000, n_surface=500)
    assert m.coverage_surface == 1.0 and m.coverage_interior == 1.0
    assert abs(m.volume_ratio - 4 / 3 * np.pi * 0.05**3 / ball.volume) < 4 * m.volume_ratio_se + 1e-3
    assert 0.0 <= m.reach_m < 0.001
    half = measure_link([(np.zeros(3), np.eye(3), np.full(3, 0.04))], [ball], n_samples=4000, n_surface=500)
    assert half.coverage_surface == 0.0 and half.volume_ratio < 0.6 and half.reach_m == 0.0


def test_fit_cache_second_load_does_not_refit(tmp_path, monkeypatch):
    from splatplan.robots import load_robot

    monkeypatch.setenv("SPLATPLAN_FIT_CACHE", str(tmp_path / "cache"))
    calls = []

    def fake(polys, cfg):  # the cache is under test here, not the fitter
        calls.append(1)
        return [mvee(np.concatenate([np.asarray(p.vertices) for p in polys]))], {}

    monkeypatch.setattr(fc, "fit_link_cover", fake)
    urdf = write_tree(tmp_path)
    r1 = load_robot(urdf, fit_method="cover")
    n = len(calls)
    assert n > 0 and len(list((tmp_path / "cache").glob("*.yaml"))) == 1
    r2 = load_robot(urdf, fit_method="cover")
    assert len(calls) == n  # read from the cache
    np.testing.assert_allclose(r1.semi_axes, r2.semi_axes, rtol=1e-12)
    assert not list(tmp_path.glob("*.ellipsoids.yaml"))  # nothing written beside the URDF
    mesh = tmp_path / "meshes" / "part.stl"  # a changed mesh file changes the key
    import trimesh

    part = trimesh.load(mesh, force="mesh")
    part.apply_scale(1.01)
    part.export(mesh)
    load_robot(urdf, fit_method="cover")
    assert len(calls) > n
    with pytest.raises(SplatplanError, match="fit method"):
        load_robot(urdf, fit_method="best")


def test_builtin_panda_models_and_finger_opening():
    from splatplan.robots import load_robot
    from splatplan.robots.builtin import DATA, PANDA_MODELS

    coarse = load_robot("panda", model="coarse")
    assert coarse.n_ellipsoids == 11
    fingers = [e for e, l in enumerate(coarse.ellipsoid_link) if "finger" in coarse.link_names[l]]
    c0, _ = coarse.ellipsoid_frames(coarse.q_default)
    wide = load_robot("panda", model="coarse", finger_opening=0.04)
    c1, _ = wide.ellipsoid_frames(wide.q_default)
    gap0 = np.linalg.norm(c0[fingers[0]] - c0[fingers[1]])
    gap1 = np.linalg.norm(c1[fingers[0]] - c1[fingers[1]])
    assert gap1 - gap0 == pytest.approx(2 * (0.04 - 0.001), abs=1e-6)
    with pytest.raises(SplatplanError, match="finger_opening"):
        load_robot("panda", finger_opening=0.05)
    with pytest.raises(SplatplanError, match="Panda model"):
        load_robot("panda", model="fine")
    with pytest.raises(SplatplanError, match="built-in 'panda' only"):
        load_robot("go2", finger_opening=0.01)
    if (DATA / PANDA_MODELS["cover"]).is_file():
        cover = load_robot("panda", model="cover")
        assert cover.n_ellipsoids > 11 and cover.dof == 7


@pytest.mark.parametrize("model", ["coarse", "cover", "tight"])
def test_shipped_panda_models_contain_random_interior_points(model):
    """Every Panda link mesh (example-robot-data): random points inside it and on its surface lie in the model."""
    import trimesh

    from splatplan.robots import load_robot
    from splatplan.robots.builtin import DATA, PANDA_MODELS, builtin_urdf
    from splatplan.robots.fit import _polytope
    from splatplan.robots.urdf import read_urdf

    if not (DATA / PANDA_MODELS[model]).is_file():
        pytest.skip(f"no shipped {model} model")
    robot = load_robot("panda", model=model)
    ref = read_urdf(builtin_urdf("panda")[0])
    rng = np.random.default_rng(3)
    for li in sorted(set(robot.ellipsoid_link.tolist())):
        link = robot.link_names[li]
        sel = np.flatnonzero(robot.ellipsoid_link == li)
        ells = [(robot.ellipsoid_local[e, :3, 3], robot.ellipsoid_local[e, :3, :3], robot.semi_axes[e]) for e in sel]
        for poly in fc.solids_of([_polytope(g, link) for g in ref.collisions[link] if g.kind in ("mesh", "box")]):
            pts = rng.uniform(poly.bounds[0], poly.bounds[1], size=(4000, 3))
            pts = pts[poly.contains(pts)]
            surf, _ = trimesh.sample.sample_surface(poly, 1000, seed=4)
            assert _inside(pts, ells).all(), link
            assert _inside(np.asarray(surf), ells).all(), link


def test_shipped_cover_model_covers_and_stays_bounded():
    """The shipped greedy-cover Panda covers every link's surface, within its measured bounds: at
    most 7 cm beyond the mesh (the base link; most links under 4 cm) and 3.5x the volume per link.
    (Measured: 1.2-6.2 cm, 1.4-2.6x, fingers 3.3x, 146 ellipsoids.)"""
    from splatplan.robots import load_robot
    from splatplan.robots.builtin import DATA, PANDA_MODELS
    from splatplan.robots.fit_measure import measure_robot

    if not (DATA / PANDA_MODELS["cover"]).is_file():
        raise AssertionError("no shipped cover model")
    robot = load_robot("panda", model="cover")
    for link, m in measure_robot(robot, n_samples=3000, n_surface=300).items():
        assert m.coverage_surface == 1.0 and m.reach_m <= 0.07 and m.volume_ratio <= 3.5, (link, m)


def test_cli_info_measures_the_model(capsys):
    import json

    from splatplan.cli import main

    assert main(["robot", "info", "panda", "--samples", "1000"]) == 0
    out = capsys.readouterr().out
    assert "model fit against" in out and "panda_hand" in out and "+-" in out
    assert main(["robot", "info", "panda", "--json", "--samples", "1000", "--finger-opening", "0.04"]) == 0
    d = json.loads(capsys.readouterr().out)
    hand = d["model_fit"]["links"]["panda_hand"]
    assert hand["n"] == 3 and hand["coverage_surface"] == 1.0  # the default tight model: 3 ellipsoids on the hand (coarse: 1) and hand["volume_ratio"] > 1.0 and hand["reach_m"] > 0.0
    assert main(["robot", "info", "panda", "--no-measure", "--json"]) == 0
    assert "model_fit" not in json.loads(capsys.readouterr().out)


@pytest.mark.skipif(not (MBM / "panda_spherized.urdf").is_file(), reason="MBM data not present")
def test_cli_info_spherized_panda_against_the_reference_meshes(capsys):
    """VAMP's sphere model measured against the MBM Panda's meshes: tight but not safe."""
    import json

    from splatplan.cli import main

    assert main(["robot", "info", str(MBM / "panda_spherized.urdf"), "--meshes-from", str(MBM / "panda.urdf"), "--json", "--samples", "2000"]) == 0
    d = json.loads(capsys.readouterr().out)
    links = {k: v for k, v in d["model_fit"]["links"].items() if v is not None}
    assert len(links) >= 8
    assert max(v["coverage_surface"] for v in links.values()) < 0.9  # spheres miss parts of every link
    assert main(["robot", "info", str(MBM / "panda_spherized.urdf"), "--meshes-from", str(MBM / "nope.urdf")]) == 2


def test_cli_fit_cover_flags_are_validated(tmp_path, capsys):
    from splatplan.cli import main

    urdf = write_tree(tmp_path)
    assert main(["robot", "fit", str(urdf), "--out", str(tmp_path / "f.yaml"), "--fit-max-per-link", "0"]) == 2
    assert "max_per_link" in capsys.readouterr().err
    with pytest.raises(SplatplanError, match="reach"):
        fc.FitConfig(reach=0.0).validate()
