"""MEAN DISTANCE GRID of the collision-only kernel: the per-voxel bound (numpy builder and the
kernel's lookup) never exceeds the true distance to the nearest mean, and the collision-only
kernel gives the same answers with and without it (and as the numpy reference), for anisotropic
splats, 2DGS disks, rotated ellipsoid links, robot batches and every n_sigma regime."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from splatplan._warp import wp as _wp
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.wp_metric import TierConfig, mean_distance_bounds
from splatplan.metric.reference import mean_distance_lb_ref
from splatplan.metric.wp_metric_kernel import mean_distance_lb_kernel

from .conftest import DEVICES, random_quats, random_scene

wp = _wp()


def _points(rng, means, n):
    """Query points: near the means, anywhere in and around their box, and far outside it."""
    lo, hi = means.min(0), means.max(0)
    ext = hi - lo
    near = means[rng.integers(0, len(means), n)] + rng.normal(scale=0.01, size=(n, 3))
    box = rng.uniform(lo - 0.5 * ext, hi + 0.5 * ext, size=(n, 3))
    far = rng.uniform(lo - 3 * ext, hi + 3 * ext, size=(n, 3))
    return np.concatenate([near, box, far, means[:n]])


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("voxels,pad", [(4096, 0.25), (2**18, 0.0), (2**18, 1.0), (1, 0.25)])
def test_lookup_is_a_lower_bound(device, voxels, pad):
    rng = np.random.default_rng(voxels)
    means = np.concatenate([rng.uniform(-0.3, 0.3, (3000, 3)), rng.normal(scale=0.02, size=(500, 3)) + 0.5]).astype(np.float32)
    lb, origin, v, lo, hi = mean_distance_bounds(means, voxels, pad)
    assert lb.size <= voxels and np.all(lb >= 0) and lb.dtype == np.float32
    pts = _points(rng, means.astype(np.float64), 4000).astype(np.float32)
    true = cKDTree(means.astype(np.float64)).query(pts.astype(np.float64))[0]
    # the kernel's lookup (the wp.func the collision kernel calls)
    from splatplan.metric.wp_metric import WarpMetric
    from splatplan.scenes.splats import Splats

    n = len(means)
    sc = Splats(means=means, quats=random_quats(rng, n), scales=np.full((n, 3), 1e-3), opacities=np.ones(n), colors=np.zeros((n, 3)))
    wm = WarpMetric(sc, device=device, tiers=TierConfig(distance_grid_voxels=voxels))
    # (the metric's grid uses the default pad; rebuild the struct with this one for the test)
    g = wm.mean_distance_grid()
    g.lb = wp.array(lb.reshape(-1), dtype=wp.float32, device=device)
    g.origin, g.inv_v = wp.vec3(*origin), float(np.float32(1.0 / v))
    g.dims = wp.vec3i(int(lb.shape[2]), int(lb.shape[1]), int(lb.shape[0]))
    g.box_lo, g.box_hi = wp.vec3(*lo), wp.vec3(*hi)
    out = wp.zeros(len(pts), dtype=wp.float32, device=device)
    wp.launch(mean_distance_lb_kernel, dim=len(pts), inputs=[g, wp.array(pts, dtype=wp.vec3, device=device), out], device=device)
    got = out.numpy()
    # the numpy twin of the lookup: the same values, but for points within float32 rounding of a voxel face
    ref = mean_distance_lb_ref(lb, origin, v, lo, hi, pts)
    f = (pts.astype(np.float64) - origin) / v
    off_face = np.all(np.abs(f - np.round(f)) > 1e-4, axis=1)
    np.testing.assert_allclose(got[off_face], ref[off_face], rtol=1e-5, atol=1e-7)
    assert np.all(ref <= true + 1e-7)
    assert np.all(got <= true + 1e-7), float((got - true).max())
    assert np.all(got >= 0)
    if voxels >= 2**18:  # the bound is useful inside the grid: close to the truth away from the means
        inside = np.all((pts >= origin) & (pts < origin + v * np.array(lb.shape[::-1])), axis=1)
        far = inside & (true > 10 * v)
        assert far.sum() > 100 and np.all(got[far] >= true[far] - 2 * np.sqrt(3) * v)


def test_builder_numpy_lookup_matches_definition():
    """Voxel (i, j, k) covers origin + v [i, i+1) x ...; every point in it is at least lb from every mean."""
    rng = np.random.default_rng(3)
    means = rng.uniform(0, 1, (800, 3)).astype(np.float32)
    lb, origin, v, lo, hi = mean_distance_bounds(means, 20_000, 0.25)
    pts = rng.uniform(origin, origin + v * np.array(lb.shape[::-1]), size=(20_000, 3))
    ijk = np.minimum(np.floor((pts - origin) / v).astype(int), np.array(lb.shape[::-1]) - 1)
    got = lb[ijk[:, 2], ijk[:, 1], ijk[:, 0]]
    true = cKDTree(means.astype(np.float64)).query(pts)[0]
    assert np.all(got <= true)
    np.testing.assert_array_equal(lo, means.min(0))
    np.testing.assert_array_equal(hi, means.max(0))


def _checkers(scene, n_sigma, device, **cfg):
    conf = MetricConfig(n_sigma=n_sigma, **cfg)
    on = CollisionChecker(scene, config=conf, device=device, tiers=TierConfig(collide_distance_grid=True, distance_grid_voxels=2**15))
    off = CollisionChecker(scene, config=conf, device=device, tiers=TierConfig(collide_distance_grid=False))
    ref = CollisionChecker(scene, config=conf, backend="reference")
    return on, off, ref


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 1.0, 3.0])
@pytest.mark.parametrize("disks", [False, True])
def test_collides_same_with_and_without_grid(device, n_sigma, disks):
    rng = np.random.default_rng(int(10 * n_sigma) + disks)
    scene = random_scene(rng, 3000, disks=disks, scale=0.006)
    on, off, ref = _checkers(scene, n_sigma, device)
    n = 3000
    centers = np.concatenate([rng.uniform(-0.45, 0.45, (n // 2, 3)), rng.uniform(-1.5, 1.5, (n // 2, 3))])
    quats = random_quats(rng, n)
    axes = rng.uniform(0.005, 0.08, (n, 3))
    axes[: n // 4] = axes[: n // 4, :1]  # spheres too
    a = np.asarray(on.collides(centers, quats, axes))
    b = np.asarray(off.collides(centers, quats, axes))
    r = np.asarray(ref.collides(centers, quats, axes))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, r)
    assert 0.02 < a.mean() < 0.98  # both answers occur


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 1.0])
def test_collides_robot_same_with_and_without_grid(device, n_sigma):
    from splatplan.robots import load_robot

    rng = np.random.default_rng(5)
    boxes = rng.uniform(-1.0, 1.0, (4000, 3)) * np.array([0.03, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])  # a wall in front of the arm
    n = len(boxes)
    scene = random_scene(rng, n, scale=0.005)
    scene.means[:] = boxes
    on, off, ref = _checkers(scene, n_sigma, device)
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((400, robot.dof)) * (lim[:, 1] - lim[:, 0])
    a = np.asarray(on.collides_robot(robot, q))
    b = np.asarray(off.collides_robot(robot, q))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a[:40], np.asarray(ref.collides_robot(robot, q[:40])))
    assert 0.0 < a.any(-1).mean() < 1.0


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 2.0])
def test_free_slack_holds(device, n_sigma):
    """An ellipsoid moved by less than its slack, in any orientation, is free (kernel without the
    grid and the numpy reference); links that collide or are not proven get 0."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(11)
    n = 4000
    scene = random_scene(rng, n, scale=0.005)
    scene.means[:] = rng.uniform(-1.0, 1.0, (n, 3)) * np.array([0.03, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])
    on, off, ref = _checkers(scene, n_sigma, device)
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((300, robot.dof)) * (lim[:, 1] - lim[:, 0])
    hits, slack = on.collides_robot_slack(robot, q)
    hits, slack = np.asarray(hits), np.asarray(slack)
    np.testing.assert_array_equal(hits, np.asarray(off.collides_robot(robot, q)))
    assert slack.shape == hits.shape and slack.dtype == np.float32 and np.all(slack >= 0)
    assert np.all(slack[hits] == 0) and 0.3 < (slack > 0).mean() < 1.0
    c, _, ax = robot.ellipsoids(q)  # (B, E, 3) host FK
    sel = np.nonzero(slack > 0)
    m = len(sel[0])
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    moved = c[sel] + d * (slack[sel] * rng.uniform(0.0, 1.0, m))[:, None]
    quats = random_quats(rng, m)
    axes = np.asarray(ax)[sel[1]]
    assert not np.asarray(off.collides(moved, quats, axes)).any()
    assert not np.asarray(ref.collides(moved[:300], quats[:300], axes[:300])).any()
    # nothing proven without the grid or with the reference backend
    _, s_off = off.collides_robot_slack(robot, q[:20])
    _, s_ref = ref.collides_robot_slack(robot, q[:5])
    assert not np.asarray(s_off).any() and not np.asarray(s_ref).any()
    h0, s0 = on.collides_robot_slack(robot, q[:0])
    assert np.asarray(h0).shape == np.asarray(s0).shape == (0, robot.n_ellipsoids)


def test_collides_robot_slack_flag_is_deprecated():
    """``collides_robot(slack=True)`` still answers (hits, slack), with a DeprecationWarning naming
    :meth:`collides_robot_slack`; the default returns the hits alone."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(1)
    scene = random_scene(rng, 500, scale=0.005)
    ch = CollisionChecker(scene, n_sigma=0.0)
    robot = load_robot("panda")
    q = robot.q_default[None]
    with pytest.warns(DeprecationWarning, match="collides_robot_slack"):
        hits, slack = ch.collides_robot(robot, q, slack=True)
    h2, s2 = ch.collides_robot_slack(robot, q)
    np.testing.assert_array_equal(hits, h2)
    np.testing.assert_array_equal(slack, s2)
    np.testing.assert_array_equal(np.asarray(ch.collides_robot(robot, q)), h2)
