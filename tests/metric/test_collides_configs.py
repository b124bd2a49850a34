"""The per-configuration collision kernel (``CollisionChecker.collides_configs``, GROUP BOUND in
:mod:`splatplan.metric.wp_metric_kernel`): the same answer as ``collides_robot(...).any(-1)`` and as
the numpy reference, on random and near-surface configurations, for anisotropic splats, 2DGS
disks and every n_sigma regime, with and without the mean-distance grid; its FREE SLACK holds (an
ellipsoid moved by less than it, in any orientation, is free); the groups follow the links."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.groups import robot_groups
from splatplan.metric.wp_metric import TierConfig

from .conftest import DEVICES, random_quats, random_scene


def _wall_scene(rng, n: int, disks: bool, scale: float = 0.005):
    """A slab of splats in front of the Panda (metres, z up)."""
    scene = random_scene(rng, n, scale=scale, disks=disks)
    scene.means[:] = rng.uniform(-1.0, 1.0, (n, 3)) * np.array([0.03, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])
    return scene


def _configs(robot, rng, n_uniform: int, near_of=None, n_near: int = 0):
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((n_uniform, robot.dof)) * (lim[:, 1] - lim[:, 0])
    if near_of is not None:  # small perturbations of configurations on both sides of the boundary
        q = np.concatenate([q, near_of[rng.integers(0, len(near_of), n_near)] + rng.normal(scale=0.03, size=(n_near, robot.dof))])
    return q


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 0.5, 1.0, 3.0])
@pytest.mark.parametrize("disks", [False, True])
def test_same_answer_as_per_ellipsoid_kernel_and_reference(device, n_sigma, disks):
    from splatplan.robots import load_robot

    rng = np.random.default_rng(int(10 * n_sigma) + 7 * disks)
    scene = _wall_scene(rng, 4000, disks, scale=0.005 / (1.0 + n_sigma))  # (big inflated splats would fill the slab)
    cfg = MetricConfig(n_sigma=n_sigma)
    on = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(distance_grid_voxels=2**15))
    off = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(collide_distance_grid=False))
    ref = CollisionChecker(scene, config=cfg, backend="reference")
    robot = load_robot("panda").inflated(0.01)
    q = _configs(robot, rng, 300)
    per_e = np.asarray(on.collides_robot(robot, q))  # (B, E)
    hit = per_e.any(-1)
    boundary = q[hit]  # near-surface: perturb colliding configurations
    q = np.concatenate([q, _configs(robot, rng, 0, boundary, 300)])
    want = np.asarray(on.collides_robot(robot, q)).any(-1)
    got = np.asarray(on.collides_configs(robot, q))
    assert got.shape == (len(q),) and got.dtype == bool
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(np.asarray(off.collides_configs(robot, q)), want)
    np.testing.assert_array_equal(np.asarray(ref.collides_configs(robot, q[::10])), want[::10])
    assert 0.1 < want.mean() < 0.9  # both answers occur
    # batch shapes: (..., dof) -> (...,)
    np.testing.assert_array_equal(np.asarray(on.collides_configs(robot, q[:60].reshape(3, 20, -1))), want[:60].reshape(3, 20))
    assert np.asarray(on.collides_configs(robot, q[:0])).shape == (0,)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 2.0])
def test_group_slack_holds(device, n_sigma):
    """Free configurations: an ellipsoid moved by less than its slack, in any orientation, is free
    (kernel without the grid and the numpy reference); colliding configurations' slack is not used."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(3 + int(n_sigma))
    scene = _wall_scene(rng, 4000, False)
    cfg = MetricConfig(n_sigma=n_sigma)
    on = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(distance_grid_voxels=2**15))
    off = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(collide_distance_grid=False))
    ref = CollisionChecker(scene, config=cfg, backend="reference")
    robot = load_robot("panda").inflated(0.01)
    q = _configs(robot, rng, 300)
    hits, slack = on.collides_configs_slack(robot, q)
    hits, slack = np.asarray(hits), np.asarray(slack)
    assert hits.shape == (300,) and slack.shape == (300, robot.n_ellipsoids) and slack.dtype == np.float32
    assert np.all(slack >= 0) and 0.3 < (slack[~hits] > 0).mean() <= 1.0
    c, _, ax = robot.ellipsoids(q)
    free = np.zeros_like(slack, dtype=bool)
    free[~hits] = True
    sel = np.nonzero(free & (slack > 0))
    m = len(sel[0])
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    moved = c[sel] + d * (slack[sel] * rng.uniform(0.0, 1.0, m))[:, None]
    quats = random_quats(rng, m)
    axes = np.asarray(ax)[sel[1]]
    assert not np.asarray(off.collides(moved, quats, axes)).any()
    assert not np.asarray(ref.collides(moved[:300], quats[:300], axes[:300])).any()
    _, s_ref = ref.collides_configs_slack(robot, q[:5])
    assert not np.asarray(s_ref).any()


def test_groups_follow_the_links():
    from splatplan.robots import load_robot

    robot = load_robot("panda")
    key, first, members, rel, ax = robot_groups(robot)
    assert sorted(members.tolist()) == list(range(robot.n_ellipsoids)) and first[0] == 0 and first[-1] == robot.n_ellipsoids
    link = np.asarray(robot.ellipsoid_link)
    for g in range(len(first) - 1):
        idx = members[first[g] : first[g + 1]]
        assert len(set(link[idx].tolist())) == 1  # one rigid body per group
    assert link[members[0]] == link.max()  # the most distal link first
    # rel: distances from the group's centroid, checked on the world-frame ellipsoid centres at two poses
    rng = np.random.default_rng(0)
    q = robot.joint_limits[:, 0] + rng.random((2, robot.dof)) * np.diff(robot.joint_limits, axis=1)[:, 0]
    c, _, _ = robot.ellipsoids(q)
    for g in range(len(first) - 1):
        idx = members[first[g] : first[g + 1]]
        for b in range(2):
            np.testing.assert_allclose(np.linalg.norm(c[b, idx] - c[b, idx].mean(0), axis=1), rel[idx], atol=1e-9)
    assert robot_groups(robot) is robot_groups(robot)  # cached on the robot
    grown = robot.inflated(0.01)
    assert robot_groups(grown)[0] != key


def test_blockers_name_faint_haze_and_the_remedy():
    """A start inside faint haze: the blockers are counted, called faint, and the remedy names the
    opacity filter; with that filter the ellipsoid is free. Inflation only: the remedy names n_sigma."""
    from splatplan.scenes.splats import Splats

    rng = np.random.default_rng(0)
    n = 2000
    means = rng.uniform(-1, 1, (n, 3))
    means[:, 2] = np.abs(means[:, 2]) + 0.3
    haze = np.array([[0.0, 0.0, 0.05]]) + rng.normal(scale=0.03, size=(20, 3))
    m = np.concatenate([means, haze])
    op = np.concatenate([np.full(n, 0.9), np.full(20, 0.05)])
    sc = np.concatenate([np.full((n, 3), 0.005), np.full((20, 3), 0.08)])
    s = Splats(m, np.tile([1.0, 0, 0, 0], (len(m), 1)), sc, op, np.full((len(m), 3), 0.5))
    paper = MetricConfig.paper()  # every splat counts (the default's opacity_min 0.1 already frees this haze)
    ch = CollisionChecker(s, n_sigma=1.0, config=paper)
    c, ax = np.array([0.0, 0.0, 0.05]), np.full(3, 0.03)
    b = ch.blockers(c, None, ax)
    ref = CollisionChecker(s, n_sigma=1.0, backend="reference", config=paper).query(c[None], None, ax)
    assert b.n == int(ref.n_colliding[0]) > 0 and b.n_faint == b.n and set(b.indices.tolist()) <= set(range(n, n + 20))
    assert "opacity" in b.remedy() and "0.3" in b.remedy() and "faint" in b.summary()
    assert not bool(np.asarray(CollisionChecker(s, config=MetricConfig(n_sigma=1.0, opacity_min=0.3)).collides(c[None], None, ax))[0])
    # an opaque splat just outside the sphere, reached by the inflation only
    s2 = Splats(np.array([[0.0, 0.0, 0.085]]), np.array([[1.0, 0, 0, 0]]), np.full((1, 3), 0.02), np.array([0.9]), np.full((1, 3), 0.5))
    b2 = CollisionChecker(s2, n_sigma=2.0, config=paper).blockers(c, None, ax)
    assert b2.n == 1 and b2.n_inside == 0 and "n_sigma" in b2.remedy()
    assert CollisionChecker(s2, n_sigma=0.0, config=paper).blockers(c, None, ax).n == 0
    # faint means inside plus an opaque splat reached by the inflation only: both remedies
    s3 = Splats(np.concatenate([haze, s2.means]), np.tile([1.0, 0, 0, 0], (21, 1)), np.concatenate([np.full((20, 3), 0.08), s2.scales]),
                np.concatenate([np.full(20, 0.05), s2.opacities]), np.full((21, 3), 0.5))
    b3 = CollisionChecker(s3, n_sigma=2.0, config=paper).blockers(c, None, ax)
    assert b3.n_faint < b3.n and b3.n_inside == b3.n_inside_faint > 0
    assert "--opacity-min 0.3" in b3.remedy() and "--linearize distance" in b3.remedy()
    # at the defaults the haze is free space, and so is the ellipsoid
    assert CollisionChecker(s, n_sigma=1.0).blockers(c, None, ax).n == 0


def test_blockers_of_a_ground_robot_say_how_high_above_the_floor():
    """A ground robot's scene (terrain removed): the blockers carry their height above the floor;
    matter standing on the floor (its inflation reaches into the step band) gets the step-height
    remedy, an obstacle higher up does not; the paper's linearisation gets its own remedy."""
    from splatplan.scenes.splats import Splats
    from splatplan.scenes.terrain import TerrainConfig, remove_terrain

    rng = np.random.default_rng(1)
    xy = rng.uniform(-1, 1, (3000, 2))
    floor = np.c_[xy, rng.normal(0.0, 0.005, 3000)]  # the floor's splats, flat
    matter = np.array([[0.0, 0.0, 0.07]])  # a rug's fold, 7 cm up, std 3 cm
    box = np.array([[0.6, 0.0, 0.30]])  # an obstacle, 30 cm up
    m = np.concatenate([floor, matter, box])
    sc = np.concatenate([np.tile([0.02, 0.02, 0.002], (3000, 1)), [[0.03, 0.03, 0.03]], [[0.03, 0.03, 0.03]]])
    s = Splats(m, np.tile([1.0, 0, 0, 0], (len(m), 1)), sc, np.full(len(m), 0.9), np.full((len(m), 3), 0.5))
    ground, _ = remove_terrain(s, TerrainConfig(floor_z=0.0))
    assert len(ground) == 2
    ch = CollisionChecker(ground)
    b = ch.blockers(np.array([0.0, 0.0, 0.12]), None, np.full(3, 0.05))
    assert b.n == 1 and b.n_floor_level == 1 and b.floor == (0.0, 0.05) and b.height[0] == pytest.approx(0.07, abs=1e-6)
    assert "above the floor" in b.summary() and "--terrain-step-height 0.08" in b.remedy()
    hi = ch.blockers(np.array([0.6, 0.0, 0.25]), None, np.full(3, 0.05))
    assert hi.n == 1 and hi.n_floor_level == 0 and "terrain" not in hi.remedy()
    # the paper's linearisation, inflation only: the remedy names the distance linearisation
    flat, c = np.array([0.3, 0.3, 0.02]), np.array([0.6, 0.0, 0.245])  # a flat link 3.5 cm under the obstacle's mean
    far = ch.with_config(linearize="squared").blockers(c, None, flat)
    assert far.n == 1 and far.n_inside == 0 and far.n_floor_level == 0 and "--linearize distance" in far.remedy()
    assert ch.blockers(c, None, flat).n == 0  # the default (distance) linearisation: free
    # a scene that is not a ground robot's: no floor
    assert CollisionChecker(s).blockers(np.array([0.6, 0.0, 0.25]), None, np.full(3, 0.05)).floor is None


def test_groups_without_link_poses_are_one_per_ellipsoid():
    """A robot that does not say where its ellipsoids sit in their links gets one group per
    ellipsoid (a shared group's radius would need those offsets)."""

    class Bare:
        semi_axes = np.array([[0.1, 0.1, 0.1], [0.05, 0.05, 0.2]])
        ellipsoid_link = np.array([0, 0])

    _, first, members, rel, _ = robot_groups(Bare())
    assert len(first) == 3 and sorted(members.tolist()) == [0, 1] and np.all(rel == 0)


def _rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotations by ``angle`` (m,) about unit ``axis`` (m, 3) (Rodrigues)."""
    k = np.zeros((len(axis), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    k = k - k.transpose(0, 2, 1)
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def _quat_to_mat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)  # fmt: skip


def _mat_to_quat(r: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotations -> (m, 4) wxyz (through scipy, an independent conversion)."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(r).as_quat()
    return np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 1.0])
@pytest.mark.parametrize("opacity", [False, True])
def test_rigid_slack_holds_near_surfaces(device, n_sigma, opacity):
    """RIGID SLACK: the answers are those of the plain check; a free ellipsoid moved rigidly (a
    rotation about a random point of it and a translation) so that none of its points moves farther
    than its slack is free by the numpy reference; links near the wall get a slack too (the FREE
    SLACK gives them 0); it is never below the FREE SLACK; target 0 is the FREE SLACK."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(11 + int(n_sigma) + 5 * opacity)
    scene = _wall_scene(rng, 4000, False)
    cfg = MetricConfig(n_sigma=n_sigma, opacity_scaled_inflation=opacity) if opacity else MetricConfig(n_sigma=n_sigma)
    on = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(distance_grid_voxels=2**15))
    ref = CollisionChecker(scene, config=cfg, backend="reference")
    robot = load_robot("panda").inflated(0.01)
    q = _configs(robot, rng, 300)
    boundary = q[np.asarray(on.collides_configs(robot, q))]
    q = np.concatenate([q, _configs(robot, rng, 0, boundary, 300)])
    target = rng.uniform(0.0, 0.05, (len(q), robot.n_ellipsoids))
    hits, slack = on.collides_configs_slack(robot, q, rigid_target=target)
    hits, slack = np.asarray(hits), np.asarray(slack)
    np.testing.assert_array_equal(hits, np.asarray(on.collides_configs(robot, q)))
    _, centre = on.collides_configs_slack(robot, q)
    centre = np.asarray(centre)
    assert np.all(slack >= 0) and not slack[hits].any()
    c, quat, ax = robot.ellipsoids(q)
    ax = np.asarray(ax)
    free = np.zeros_like(slack, dtype=bool)
    free[~hits] = True
    near = free & (centre == 0) & (slack > 0)
    assert near.sum() > 20  # links near the wall are proven free over a distance too
    assert np.all(slack[free] >= centre[free])  # (the FREE SLACK is a rigid one too: it is kept where larger)
    np.testing.assert_array_equal(np.asarray(on.collides_configs_slack(robot, q, rigid_target=0.0)[1])[~hits], centre[~hits])  # target 0: the FREE SLACK
    sel = np.nonzero(free & (slack > 0))
    m = len(sel[0])
    a = ax[sel[1]]  # (m, 3)
    r0 = _quat_to_mat(np.asarray(quat)[sel])  # (m, 3, 3) world <- ellipsoid
    # a rotation about a random point p of the ellipsoid (link frame u, |u / a| <= 1) then a translation;
    # every point x = c + R0 v (|v / a| <= 1) moves by (R - I) R0 (v - u) + t: at most |R - I| 2 a_max + |t|
    axis = rng.normal(size=(m, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    u = rng.normal(size=(m, 3))
    u = u / np.linalg.norm(u, axis=1, keepdims=True) * a * rng.uniform(0, 1, (m, 1))
    split = rng.uniform(0.0, 1.0, m)
    budget = slack[sel] * rng.uniform(0.5, 0.999, m)
    angle = 2 * np.arcsin(np.clip(split * budget / (2 * 2 * a.max(1)), 0, 1))  # |R - I| = 2 sin(angle / 2)
    rot = _rotation(axis, angle)
    t = rng.normal(size=(m, 3))
    t = t / np.linalg.norm(t, axis=1, keepdims=True) * ((1 - split) * budget)[:, None]
    pw = c[sel] + np.einsum("mij,mj->mi", r0, u)  # the pivot (world)
    c_new = pw + np.einsum("mij,mj->mi", rot, c[sel] - pw) + t
    r_new = rot @ r0
    # (the bound on the displacement holds: check it on the ellipsoid's extreme points)
    for s in (-1, 1):
        for k in range(3):
            v = np.zeros((m, 3))
            v[:, k] = s * a[:, k]
            x0 = c[sel] + np.einsum("mij,mj->mi", r0, v)
            x1 = c_new + np.einsum("mij,mj->mi", r_new, v)
            assert np.all(np.linalg.norm(x1 - x0, axis=1) <= budget * (1 + 1e-9))
    is_near = near[sel]
    pick = np.concatenate([np.nonzero(is_near)[0], rng.permutation(np.nonzero(~is_near)[0])[:1500]])  # every near link
    got = np.asarray(ref.collides(c_new[pick], _mat_to_quat(r_new[pick]), a[pick]))
    assert not got.any()


def test_rigid_target_bad_input_is_named():
    from splatplan.errors import SplatplanError
    from splatplan.robots import load_robot

    rng = np.random.default_rng(0)
    ch = CollisionChecker(_wall_scene(rng, 500, False), device="cpu")
    robot = load_robot("panda")
    q = np.tile(robot.q_default, (4, 1))
    for bad, words in ((np.nan, "finite"), (-0.01, ">= 0"), (np.zeros((4, 3)), "broadcast")):
        for ws in (None, ch.workspace()):
            with pytest.raises(SplatplanError, match="rigid_target") as e:
                ch.collides_configs_slack(robot, q, out=ws, rigid_target=bad)
            assert words in str(e.value)
    h, s = ch.collides_configs_slack(robot, q, rigid_target=0.01)  # a scalar broadcasts
    assert np.asarray(s).shape == (4, robot.n_ellipsoids)
