"""RRT with a Robot: the edge-resolution guarantee, joint-space planning for the Panda, planar
bases, scene-scaled defaults, time limit and scene-bounds errors."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import PlanningError, SplatplanError
from splatplan.planners import RRT, RRTConfig, edge_samples, plan
from splatplan.planners.robot_links import LinkGeometry
from splatplan.robots import load_robot
from splatplan.scenes.splats import Splats, quat_to_rotmat

from .scenes import make_checker, make_scene

robots = pytest.importorskip("splatplan.robots")


def _surface_points(robot, q: np.ndarray, n_dirs: int = 32) -> np.ndarray:
    """(..., dof) -> (..., E * n_dirs, 3): points on every ellipsoid's surface (and its centre)."""
    rng = np.random.default_rng(1)
    u = rng.normal(size=(n_dirs, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u[0] = 0.0  # the centre itself
    c, quat, ax = robot.ellipsoids(q)  # (..., E, 3), (..., E, 4), (E, 3)
    r = quat_to_rotmat(quat.reshape(-1, 4)).reshape(quat.shape[:-1] + (3, 3))  # (..., E, 3, 3)
    local = u[None, :, :] * ax[:, None, :]  # (E, n_dirs, 3) ellipsoid frame
    pts = c[..., :, None, :] + np.einsum("...eij,edj->...edi", r, local)  # (..., E, n_dirs, 3)
    return pts.reshape(q.shape[:-1] + (-1, 3))


@pytest.mark.parametrize("name", ["panda", "go2", "sphere:0.02", "ellipsoid:0.05,0.02,0.01"])
def test_edge_resolution_guarantee(name):
    """Between consecutive check configurations no ellipsoid point moves more than the resolution."""
    robot = robots.load_robot(name)
    geom = LinkGeometry(robot)
    rng = np.random.default_rng(0)
    lim = robot.joint_limits
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -1.0)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], 1.0)
    a = lo + rng.random((8, robot.dof)) * (hi - lo)
    b = np.clip(a + rng.normal(scale=0.1, size=a.shape), lo, hi)
    res = RRTConfig().edge_fraction * robot.min_semi_axis
    pts, idx, n = edge_samples(a, b, geom.motion(b - a), res)
    assert pts.shape == (int(n.sum()), robot.dof)
    # prepend each edge's start: consecutive check configurations along every edge
    chain = np.concatenate([np.concatenate([a[e : e + 1], pts[idx == e]]) for e in range(len(a))])
    first = np.concatenate([[0], np.cumsum(n + 1)[:-1]])
    sp = _surface_points(robot, chain)  # (P, M, 3)
    disp = np.linalg.norm(np.diff(sp, axis=0), axis=-1).max(axis=1)  # (P - 1,)
    within = np.ones(len(chain) - 1, dtype=bool)
    within[first[1:] - 1] = False  # pairs that straddle two edges
    assert disp[within].max() <= res * (1 + 1e-9), (name, disp[within].max(), res)
    np.testing.assert_allclose(pts[np.cumsum(n) - 1], b)  # each edge ends at b


@pytest.fixture(scope="module")
def panda_checker():
    # a wall in front of the Panda (base at the origin): turning the arm from one side to the other
    # through the wall's side needs a detour over or around it
    scene = make_scene([((0.25, -0.2, 0.3), (0.3, 0.2, 0.9))], spacing=0.03)
    return make_checker(scene, n_sigma=1.0)


def test_panda_joint_space_path_is_free(panda_checker):
    robot = robots.load_robot("panda")
    q1, q2 = robot.q_default.copy(), robot.q_default.copy()
    q1[0], q2[0] = 1.4, -1.4
    geom = LinkGeometry(robot)
    assert geom.collides(panda_checker, (q1 + q2)[None] / 2).all()  # the straight joint path hits the wall
    rrt = RRT(panda_checker, RRTConfig(seed=0, time_limit_s=40.0), robot=robot)
    res = rrt.plan(q1, q2)
    assert res.success, res.message
    np.testing.assert_allclose(res.path[0], q1)
    np.testing.assert_allclose(res.path[-1], q2)
    lim = robot.joint_limits
    assert np.all(res.path >= lim[:, 0] - 1e-12) and np.all(res.path <= lim[:, 1] + 1e-12)
    st = res.info["settings"]
    assert st["edge_resolution"] == pytest.approx(0.25 * robot.min_semi_axis)
    # independent re-check: every edge at the stated resolution, every ellipsoid, no collision
    p = res.path
    pts, _, _ = edge_samples(p[:-1], p[1:], geom.motion(np.diff(p, axis=0)), st["edge_resolution"])
    c, quat, ax = robot.ellipsoids(pts)
    assert not panda_checker.collides(c, quat, ax).any()


def test_planar_base_robot_samples_x_y_yaw():
    robot = robots.load_robot("go2")
    # two posts the dog must pass between / around, standing on z = 0
    scene = make_scene([((-0.1, -1.0, 0.0), (0.1, -0.4, 0.6)), ((-0.1, 0.4, 0.0), (0.1, 1.0, 0.6)),
                        ((-1.5, -1.5, 0.0), (-1.4, 1.5, 0.05)), ((1.4, -1.5, 0.0), (1.5, 1.5, 0.05))], spacing=0.05)  # fmt: skip
    ch = make_checker(scene, n_sigma=0.5)
    rrt = RRT(ch, RRTConfig(seed=0, time_limit_s=30.0), robot=robot)
    st = rrt.settings((-0.9, 0.0, 0.0), (0.9, 0.0, 0.0))
    assert st.box_lo[2] == pytest.approx(-np.pi) and st.box_hi[2] == pytest.approx(np.pi)
    assert st.box_lo[0] < -1.4 and st.box_hi[0] > 1.4  # x, y from the scene bounds
    res = rrt.plan((-0.9, 0.0, 0.0), (0.9, 0.0, 0.0))
    assert res.success, res.message
    assert not LinkGeometry(robot).collides(ch, res.path).any()


def _scaled(s: Splats, k: float) -> Splats:
    return Splats(s.means * k, s.quats, s.scales * k, s.opacities, s.colors)


def test_scene_scaled_defaults_scale_with_the_scene():
    base = make_scene([((-0.5, -0.5, 0.0), (0.5, 0.5, 0.3))], spacing=0.05)
    start, goal = np.array([-0.3, 0.0, 0.15]), np.array([0.3, 0.1, 0.15])
    out = {}
    for k in (1.0, 7.0):
        ch = make_checker(_scaled(base, k), n_sigma=1.0)
        st = RRT(ch, RRTConfig(), robot=load_robot(f"sphere:{0.015 * k!r}")).settings(start * k, goal * k)
        assert set(st.derived) >= {"stride", "edge_resolution", "goal_tolerance", "box"}
        out[k] = st
    a, b = out[1.0], out[7.0]
    for name in ("stride", "edge_resolution", "goal_tolerance", "connect_radius"):
        assert getattr(b, name) == pytest.approx(7.0 * getattr(a, name), rel=1e-6), name
    np.testing.assert_allclose(b.box_lo, 7.0 * a.box_lo, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(b.box_hi, 7.0 * a.box_hi, rtol=1e-5, atol=1e-9)
    assert a.stride == pytest.approx(np.max(a.box_hi - a.box_lo) / 32)
    assert a.edge_resolution == pytest.approx(0.015 / 4)
    assert "stride*" in a.summary() and "time limit 10 s" in a.summary()


def test_robust_box_ignores_outliers_and_goal_outside_is_an_error():
    s = make_scene([((-0.5, -0.5, 0.0), (0.5, 0.5, 0.3))], spacing=0.05)
    far = Splats(np.array([[40.0, 0, 0], [0, -60.0, 5.0]]), np.tile([1.0, 0, 0, 0], (2, 1)), np.full((2, 3), 0.01), np.full(2, 0.9), np.full((2, 3), 0.5))
    scene = Splats(*(np.concatenate([getattr(s, f), getattr(far, f)]) for f in ("means", "quats", "scales", "opacities", "colors")))
    ch = make_checker(scene, n_sigma=1.0)
    st = RRT(ch, RRTConfig(), robot="sphere:0.015").settings((-0.3, 0.0, 0.15), (0.3, 0.1, 0.15))
    assert np.all(st.box_hi < 0.6) and np.all(st.box_lo > -0.6)  # the two outliers do not stretch it
    with pytest.raises(PlanningError, match="outside the scene bounds"):
        RRT(ch, RRTConfig(), robot="sphere:0.015").plan((-0.3, 0.0, 0.15), (0.3, 0.1, 90.0))


def test_time_limit_and_message():
    # the goal is sealed inside a closed box: no path exists
    scene = make_scene([((-0.5, -0.5, 0.0), (0.5, 0.5, 0.3)), ((0.1, -0.1, 0.05), (0.3, 0.1, 0.25))], spacing=0.01)
    ch = make_checker(scene, n_sigma=1.0)
    res = RRT(ch, RRTConfig(time_limit_s=0.3, seed=0), robot="sphere:0.015").plan((-0.3, 0.0, 0.15), (0.2, 0.0, 0.15))
    assert not res.success and res.info.get("time_limit_hit")
    assert res.message.startswith("no path found within 0.3 s (") and res.message.endswith(" nodes)")


def test_plan_takes_only_a_robot_a_name_and_a_robot_agree():
    scene = make_scene([((-0.01, -0.25, 0.0), (0.01, 0.12, 0.12))])
    ch = make_checker(scene, n_sigma=1.0)
    cfg = RRTConfig(box_lo=(-0.25, -0.3, 0.06), box_hi=(0.25, 0.3, 0.06), seed=3)
    a = plan(ch, (-0.15, 0.0, 0.06), (0.15, 0.0, 0.06), robot=load_robot("sphere:0.015"), refine=False, rrt_config=cfg)
    b = plan(ch, (-0.15, 0.0, 0.06), (0.15, 0.0, 0.06), robot="sphere:0.015", refine=False, rrt_config=cfg)
    assert a.success and b.success
    np.testing.assert_allclose(a.path, b.path)
    with pytest.raises(SplatplanError, match="give the robot"):
        plan(ch, (-0.15, 0.0, 0.06), (0.15, 0.0, 0.06), robot=None, rrt_config=cfg)
    with pytest.raises(TypeError):  # no radius path, no default robot
        plan(ch, (-0.15, 0.0, 0.06), (0.15, 0.0, 0.06), radius=0.015)  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        RRT(ch, cfg)  # type: ignore[call-arg]
