"""Robot: loading, validation, motion bound, self-collision, bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.robots import load_robot

from .conftest import random_q, write_tree


def _surface_points(robot, q, n_per=64, seed=0):
    """World points on every ellipsoid's surface (..., E*n_per, 3) for configurations q (..., dof)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(robot.n_ellipsoids, n_per, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    local = u * robot.semi_axes[:, None, :]  # (E, n, 3) ellipsoid frame
    c, r = robot.ellipsoid_frames(q)  # (..., E, 3), (..., E, 3, 3)
    pts = np.einsum("...eij,enj->...eni", r, local) + c[..., :, None, :]
    return pts.reshape(pts.shape[:-3] + (-1, 3))


def test_builtins_basic(panda, go2):
    assert panda.dof == 7 and panda.joint_names[0] == "panda_joint1" and panda.n_ellipsoids == 43  # the tight model (DEFAULT_MODEL, data/panda_tight.yaml)
    assert load_robot("panda:coarse").n_ellipsoids == load_robot("panda", model="coarse").n_ellipsoids == 11  # the named coarse option: one per link
    assert go2.dof == 3 and go2.joint_names == ["x", "y", "yaw"]
    s = load_robot("sphere:0.015")
    assert s.dof == 3 and s.n_ellipsoids == 1 and s.min_semi_axis == pytest.approx(0.015)
    e = load_robot("ellipsoid:0.05,0.02,0.01")
    c, q, a = e.ellipsoids(np.array([[1.0, 2.0, 3.0]]))
    np.testing.assert_allclose(c[0, 0], [1, 2, 3])
    np.testing.assert_allclose(q[0, 0], [1, 0, 0, 0])
    np.testing.assert_allclose(a[0], [0.05, 0.02, 0.01])
    for r in (panda, go2, s):
        assert r.joint_limits.shape == (r.dof, 2) and r.velocity_limits.shape == (r.dof,)
        assert r.motion_bound.shape == (r.dof,) and np.all(r.motion_bound > 0)
        assert not r.self_collision(r.q_default)
        assert np.all(r.q_default >= r.joint_limits[:, 0]) and np.all(r.q_default <= r.joint_limits[:, 1])


def test_go2_stands_on_the_ground(go2):
    for q in random_q(go2, 5, seed=1):
        pts = _surface_points(go2, q, n_per=400)
        assert pts[:, 2].min() > -1e-3  # lowest ellipsoid point at z = 0 (sampled surface: within 1 mm)
    c, r = go2.ellipsoid_frames(go2.q_default)
    low = c[:, 2] - np.linalg.norm(r[:, 2, :] * go2.semi_axes, axis=-1)
    assert low.min() == pytest.approx(0.0, abs=1e-9)
    assert 0.25 < go2.base_pose[2, 3] < 0.45


@pytest.mark.parametrize("name", ["panda", "go2", "sphere:0.015", "tree"])
def test_motion_bound_property(name, tree_robot):
    """|x(q1) - x(q2)| <= sum_j motion_bound_j |q1_j - q2_j| for every ellipsoid point."""
    robot = tree_robot if name == "tree" else load_robot(name)
    q1 = random_q(robot, 200, seed=2)
    # both far pairs and near pairs (the bound is used for short edges)
    q2 = np.concatenate([random_q(robot, 100, seed=3), q1[100:] + np.random.default_rng(4).normal(scale=0.05, size=(100, robot.dof))])
    d = np.linalg.norm(_surface_points(robot, q1, 16) - _surface_points(robot, q2, 16), axis=-1).max(axis=-1)
    bound = np.abs(q1 - q2) @ robot.motion_bound
    assert np.all(d <= bound + 1e-12)


def test_check_q(panda):
    q = panda.q_default
    assert panda.check_q(q).dtype == np.float64
    with pytest.raises(SplatplanError, match="need 7 values"):
        panda.check_q(np.zeros(6))
    with pytest.raises(SplatplanError, match="NaN"):
        panda.check_q(np.array([q, np.full(7, np.nan)]))
    bad = q.copy()
    bad[3] = 0.5  # joint 4 upper limit is -0.0698
    with pytest.raises(SplatplanError, match="panda_joint4 = 0.5 outside its limits"):
        panda.check_q(bad)
    assert panda.check_q(bad, clip=True)[3] == pytest.approx(-0.0698)
    assert panda.check_q(bad, check_limits=False)[3] == 0.5
    with pytest.raises(SplatplanError, match="NaN"):
        panda.link_poses(np.full(7, np.nan))
    with pytest.raises(SplatplanError, match="numeric"):
        panda.check_q("abc")


def test_self_collision(panda):
    """Conservative: every sampled true overlap is reported; pairs declared apart are apart."""
    q = random_q(panda, 300, seed=5)
    sc = panda.self_collision(q)
    assert sc.shape == (300,) and sc.any() and not sc.all()
    c, r = panda.ellipsoid_frames(q)
    pts = _surface_points(panda, q, 200).reshape(300, panda.n_ellipsoids, 200, 3)
    overlap = np.zeros(300, dtype=bool)
    for i, j in panda.self_collision_pairs:
        for a, b in ((i, j), (j, i)):
            cand = np.concatenate([pts[:, a], c[:, a, None, :]], axis=1)  # surface samples + centre of a
            local = np.einsum("bki,bnk->bni", r[:, b], cand - c[:, b, None, :]) / panda.semi_axes[b]
            overlap |= np.linalg.norm(local, axis=-1).min(axis=-1) <= 1.0
    assert overlap.any()  # the sample holds real self-collisions
    assert np.all(sc[overlap])  # none missed
    assert panda.self_collision(q.reshape(3, 100, 7)).shape == (3, 100)


def test_unknown_and_bad_specs(tmp_path):
    with pytest.raises(SplatplanError, match="panda, go2, sphere:R"):
        load_robot("ur5")
    for spec, msg in [("sphere:x", "numbers"), ("sphere:0", "> 0"), ("ellipsoid:1,2", "not understood"), ("sphere:nan", "finite"), ("panda:fine", "unknown Panda model 'fine'")]:
        with pytest.raises(SplatplanError, match=msg):
            load_robot(spec)
    with pytest.raises(SplatplanError, match="names model 'coarse' but model='tight'"):
        load_robot("panda:coarse", model="tight")
    with pytest.raises(SplatplanError, match="does not exist"):
        load_robot(tmp_path / "missing.urdf")
    p = tmp_path / "broken.urdf"
    p.write_text("<robot name='x'><link name='a'></robot")
    with pytest.raises(SplatplanError, match="does not parse"):
        load_robot(p)
    p.write_text("<foo/>")
    with pytest.raises(SplatplanError, match="root element is <foo>"):
        load_robot(p)
    p.write_text('<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="floating"><parent link="a"/><child link="b"/></joint></robot>')
    with pytest.raises(SplatplanError, match="unsupported type 'floating'"):
        load_robot(p)
    p.write_text('<robot name="r"><link name="a"/></robot>')
    with pytest.raises(SplatplanError, match="no link has collision geometry"):
        load_robot(p)
    p.write_text('<robot name="r"><link name="a"><collision><geometry><box size="1 1 1"/></geometry></collision></link></robot>')
    static = load_robot(p, fit_method="split")  # zero dof: a rigid object
    assert static.dof == 0 and static.fk(np.zeros((2, 0)))[0].shape == (2, 1, 3)
    with pytest.raises(SplatplanError, match="unknown or non-movable joints"):
        load_robot("panda", active=["nope"])


def test_missing_mesh_and_links_without_geometry(tmp_path):
    p = write_tree(tmp_path, with_mesh=False)
    with pytest.raises(SplatplanError, match=r"link 'l4': mesh file .*part.stl not found"):
        load_robot(p)
    p = write_tree(tmp_path)
    r = load_robot(p, fit_method="split")
    assert r.skipped_links == ["l6"] and "l6" not in {r.link_names[l] for l in r.ellipsoid_link}


def test_options(tree_urdf):
    r = load_robot(tree_urdf, active=["j1", "j3"], fixed={"j2": 0.1}, base="planar", fit_method="split")
    assert r.joint_names == ["x", "y", "yaw", "j1", "j3"]
    q = np.zeros(5)
    q[:3] = [1.0, -2.0, 0.5]
    poses = r.link_poses(q)
    np.testing.assert_allclose(poses[0, :3, 3], [1.0, -2.0, 0.0])
    r3 = load_robot(tree_urdf, base="translation", base_pose=np.diag([1.0, 1.0, 1.0, 1.0]), fit_method="split")
    assert r3.joint_names[:3] == ["x", "y", "z"]
    with pytest.raises(SplatplanError, match="base_pose"):
        load_robot(tree_urdf, base_pose=np.ones((4, 4)))
    with pytest.raises(SplatplanError, match="base 'wheeled'"):
        load_robot(tree_urdf, base="wheeled")


def test_go2_front_hips_are_covered(go2):
    """The URDF gives the front hips no collision geometry; their visual meshes lie inside the other ellipsoids."""
    pytest.importorskip("collada", reason="the Go2's visual meshes are COLLADA (.dae): pycollada not installed")
    from splatplan.robots.fit import link_points, mahalanobis
    from splatplan.robots.urdf import read_urdf

    model = read_urdf(go2.info["urdf"])
    poses = go2.link_poses(go2.q_default)
    c, r = go2.ellipsoid_frames(go2.q_default)
    for link in ("FL_hip", "FR_hip"):
        assert link in go2.skipped_links
        li = go2.link_names.index(link)
        pts = link_points(model.visuals[link], link) @ poses[li, :3, :3].T + poses[li, :3, 3]
        inside = np.zeros(len(pts), dtype=bool)
        for e in range(go2.n_ellipsoids):
            inside |= mahalanobis(pts, c[e], r[e], go2.semi_axes[e]) <= 1.0
        assert inside.all(), link


def test_pickle_round_trip(panda):
    import pickle

    r2 = pickle.loads(pickle.dumps(panda))
    q = panda.q_default
    np.testing.assert_allclose(r2.fk(q[None])[0], panda.fk(q[None])[0])


def test_parse_robot_name_is_the_one_parser():
    from splatplan.robots import (
        DEFAULT_POINT_ROBOT,
        ROBOT_NAME_HELP,
        parse_robot_name,
        point_radius,
    )

    assert parse_robot_name(" sphere:0.02 ") == parse_robot_name("sphere:0.02")
    s = parse_robot_name("sphere:0.02")
    assert s.kind == "sphere" and s.semi_axes == (0.02, 0.02, 0.02) and s.is_point
    e = parse_robot_name("ellipsoid:0.01,0.02,0.03")
    assert e.kind == "ellipsoid" and e.semi_axes == (0.01, 0.02, 0.03)
    assert parse_robot_name("panda").kind == "panda" and not parse_robot_name("panda").is_point
    assert parse_robot_name("arm.urdf").kind == "path"
    for spec, msg in [("sphere:x", "numbers"), ("sphere:-1", "> 0"), ("ellipsoid:1,2", "not understood"), ("ellipsoid:1,inf,1", "finite")]:
        with pytest.raises(SplatplanError, match=msg):
            parse_robot_name(spec)
    # the robot load_robot builds is the parsed one
    r = load_robot("ellipsoid:0.01,0.02,0.03")
    np.testing.assert_array_equal(r.semi_axes, [[0.01, 0.02, 0.03]])
    assert r.name == "ellipsoid:0.01,0.02,0.03" and r.joint_names == ["x", "y", "z"]
    assert r.is_point and load_robot("sphere:0.02", base_pose=np.eye(4)).is_point
    assert not load_robot("go2").is_point and not load_robot("panda").is_point  # 3 dofs, but a planar base
    assert point_radius() == 0.015 and load_robot(DEFAULT_POINT_ROBOT).min_semi_axis == point_radius()
    with pytest.raises(SplatplanError, match="not a sphere"):
        point_radius("ellipsoid:1,2,3")
    for word in ("panda", "go2", "sphere:R", "ellipsoid:A,B,C", "urdf"):
        assert word in ROBOT_NAME_HELP


def test_cli_uses_the_one_help_text():
    from splatplan.cli import build_parser
    from splatplan.robots import ROBOT_NAME_HELP

    for cmd in ("plan", "check", "view"):
        sub = next(a for a in build_parser()._actions if a.dest == "cmd").choices[cmd]
        robot = next(a for a in sub._actions if a.dest == "robot")
        assert ROBOT_NAME_HELP in robot.help, cmd


@pytest.mark.parametrize("name", ["panda", "go2", "sphere:0.02"])
def test_load_robot_returns_a_fresh_robot(name):
    a, b = load_robot(name), load_robot(name)
    assert a is not b
    # nothing mutable is shared: not the arrays, the kinematics, the lock or the thread pool
    for attr in ("semi_axes", "motion_bound", "joint_limits", "q_default", "ellipsoid_local", "kin", "info", "_lock", "_wp_cache"):
        assert getattr(a, attr) is not getattr(b, attr), attr
    a.semi_axes[0] *= 2.0
    a.q_default[0] += 0.1
    c = load_robot(name)
    np.testing.assert_array_equal(c.semi_axes, b.semi_axes)
    np.testing.assert_array_equal(c.q_default, b.q_default)
    a.fk(a.q_default[None])  # a's pool and caches are a's
    a.close()
    np.testing.assert_allclose(b.fk(b.q_default[None])[0], c.fk(c.q_default[None])[0])


def test_point_robot_as_a_planar_base_matches_the_planar_dynamics_body():
    """The same body through two representations: ``load_robot("ellipsoid:A,B,C", base="planar")``
    and PlanarBase's own geometry (height, one ellipsoid at the origin) give the same ellipsoids."""
    from splatplan.planners import PlanarBase

    lift = np.eye(4)
    lift[2, 3] = 0.06
    body = load_robot("ellipsoid:0.03,0.015,0.012", base="planar", base_pose=lift)
    assert body.joint_names == ["x", "y", "yaw"] and not body.is_point and list(body.continuous) == [False, False, True]
    q = np.random.default_rng(0).uniform([-1, -1, -np.pi], [1, 1, np.pi], (50, 3))
    c, quat, ax = body.ellipsoids(q)
    c2, quat2, ax2 = PlanarBase(height=0.06).link_poses(q)
    np.testing.assert_allclose(c, c2, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(quat * quat2, axis=-1)), 1.0, atol=1e-12)  # same rotation (q or -q)
    np.testing.assert_allclose(ax, ax2)
    np.testing.assert_allclose(body.fk(q)[0], c, atol=1e-5)  # the Warp kernel agrees
    with pytest.raises(SplatplanError, match="base 'fixed'"):
        load_robot("sphere:0.1", base="fixed")
    with pytest.raises(SplatplanError, match="per_link, model apply to URDF robots"):
        load_robot("sphere:0.1", per_link=2, model="cover")


@pytest.mark.parametrize("name", ["panda", "go2", "sphere:0.015", "tree"])
def test_ellipsoid_motion_bounds_property(name, tree_robot):
    """|x(q1) - x(q2)| <= sum_j B[e, j] |q1_j - q2_j| for every point x of ellipsoid e, B <= motion_bound."""
    robot = tree_robot if name == "tree" else load_robot(name)
    b = robot.ellipsoid_motion_bounds()
    assert b.shape == (robot.n_ellipsoids, robot.dof) and np.all(b >= 0)
    assert np.all(b.max(axis=0) <= robot.motion_bound + 1e-12)
    q1 = random_q(robot, 200, seed=5)
    q2 = np.concatenate([random_q(robot, 100, seed=6), q1[100:] + np.random.default_rng(7).normal(scale=0.05, size=(100, robot.dof))])
    n_per = 16
    d = np.linalg.norm(_surface_points(robot, q1, n_per) - _surface_points(robot, q2, n_per), axis=-1)  # (B, E*n_per)
    d = d.reshape(len(q1), robot.n_ellipsoids, n_per).max(axis=-1)  # (B, E)
    bound = np.abs(q1 - q2) @ b.T
    assert np.all(d <= bound + 1e-12)
    if name == "panda":
        assert not b[0].any()  # the base link's ellipsoid moves with no joint
