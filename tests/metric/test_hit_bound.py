"""HIT BOUND of the collision-only kernels: the per-voxel upper bound on the distance to the nearest
counted mean (numpy builder, its numpy twin and the kernel's lookup) never falls below the truth,
and the collision answers with it equal those without it and the numpy reference, per ellipsoid
and per configuration, for every n_sigma regime, with the opacity rule and with ``k_collide`` > 0
(where it must stay unused)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from splatplan._warp import wp as _wp
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.reference import hit_bound_ref
from splatplan.metric.tiers import TierConfig, mean_distance_bounds, mean_distance_upper
from splatplan.metric.wp_metric import WarpMetric, metric_params
from splatplan.metric.wp_metric_kernel import hit_bound_kernel

from .conftest import DEVICES, random_quats, random_scene

wp = _wp()


def _means(rng, n=3000):
    return np.concatenate([rng.uniform(-0.3, 0.3, (n, 3)), rng.normal(scale=0.02, size=(n // 6, 3)) + 0.5]).astype(np.float32)


@pytest.mark.parametrize("voxels", [4096, 2**17])
def test_upper_bound_holds(voxels):
    rng = np.random.default_rng(voxels)
    means = _means(rng)
    lb, origin, v, _, _ = mean_distance_bounds(means, voxels)
    ub = mean_distance_upper(means, origin, v, lb.shape)
    assert ub.shape == lb.shape and ub.dtype == np.float32
    dims = np.array(lb.shape[::-1])
    pts = rng.uniform(origin, origin + v * dims, size=(20_000, 3))
    ijk = np.minimum(np.floor((pts - origin) / v).astype(int), dims - 1)
    got = ub[ijk[:, 2], ijk[:, 1], ijk[:, 0]].astype(np.float64)
    true = cKDTree(means.astype(np.float64)).query(pts)[0]
    assert np.all(got >= true), float((true - got).max())
    assert np.all(ub >= lb)
    # useful: within two voxel diagonals of the truth (the nearest occupied voxel's mean, plus the voxel's half-diagonal)
    assert np.all(got <= true + 2 * np.sqrt(3) * v * 1.01)
    # the voxels holding a mean bound it by at most their diagonal
    occ = np.minimum(np.floor((means.astype(np.float64) - origin) / v).astype(int), dims - 1)
    assert np.all(ub[occ[:, 2], occ[:, 1], occ[:, 0]] <= np.sqrt(3) * v * 1.01)


def test_upper_bound_of_no_means_is_infinite():
    ub = mean_distance_upper(np.zeros((0, 3), np.float32), np.zeros(3), 0.1, (2, 3, 4))
    assert ub.shape == (2, 3, 4) and np.all(np.isinf(ub))


@pytest.mark.parametrize("device", DEVICES)
def test_kernel_lookup_matches_numpy_twin(device):
    rng = np.random.default_rng(2)
    means = _means(rng)
    n = len(means)
    sc = random_scene(rng, n, scale=0.004)
    sc.means[:] = means
    wm = WarpMetric(sc, device=device, tiers=TierConfig(distance_grid_voxels=2**16))
    cfg = MetricConfig(n_sigma=1.0, opacity_min=0.0, opacity_scaled_inflation=False)
    g = wm.mean_distance_grid(0.0)
    assert g.use_ub == 1
    lb, origin, v, _, _ = mean_distance_bounds(wm._means_np, 2**16)
    ub = mean_distance_upper(wm._means_np, origin, v, lb.shape)
    np.testing.assert_array_equal(g.ub.numpy(), ub.reshape(-1))
    pts = np.concatenate([means[:2000] + rng.normal(scale=0.02, size=(2000, 3)), rng.uniform(-1.5, 1.5, (2000, 3))]).astype(np.float32)
    a_min = rng.uniform(0.005, 0.08, len(pts)).astype(np.float32)
    out = wp.zeros(len(pts), dtype=wp.bool, device=device)
    wp.launch(hit_bound_kernel, dim=len(pts), inputs=[g, metric_params(cfg, 0, 1), wp.array(pts, dtype=wp.vec3, device=device),
                                                      wp.array(a_min, dtype=wp.float32, device=device), out], device=device)  # fmt: skip
    got = out.numpy()
    ref = hit_bound_ref(ub, origin, v, pts, a_min)
    f = (pts.astype(np.float64) - origin) / v
    off_face = np.all(np.abs(f - np.round(f)) > 1e-4, axis=1)
    np.testing.assert_array_equal(got[off_face], ref[off_face])
    assert 0.05 < got.mean() < 0.95  # both answers occur
    # the points it calls hits hold a mean within a_min
    true = cKDTree(means.astype(np.float64)).query(pts.astype(np.float64))[0]
    assert np.all(true[got] < a_min[got])
    # k_collide > 0: never used
    p1 = metric_params(MetricConfig(n_sigma=1.0, k_collide=1, opacity_min=0.0, opacity_scaled_inflation=False), 0, 1)
    wp.launch(hit_bound_kernel, dim=len(pts), inputs=[g, p1, wp.array(pts, dtype=wp.vec3, device=device), wp.array(a_min, dtype=wp.float32, device=device), out], device=device)
    assert not out.numpy().any()


def _checkers(scene, device, **cfg):
    conf = MetricConfig(**cfg)
    tiers = dict(collide_distance_grid=True, distance_grid_voxels=2**15)
    on = CollisionChecker(scene, config=conf, device=device, tiers=TierConfig(collide_hit_grid=True, **tiers))
    off = CollisionChecker(scene, config=conf, device=device, tiers=TierConfig(collide_hit_grid=False, **tiers))
    ref = CollisionChecker(scene, config=conf, backend="reference")
    return on, off, ref


REGIMES = [
    dict(n_sigma=0.0),
    dict(n_sigma=1.0),
    dict(n_sigma=3.0, linearize="squared", opacity_min=0.0, opacity_scaled_inflation=False),
    dict(n_sigma=1.0, opacity_min=0.4),  # faint splats are free space: the bound counts only the others
    dict(n_sigma=0.0, k_collide=2),
]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("regime", range(len(REGIMES)))
def test_collides_same_with_and_without_hit_bound(device, regime):
    rng = np.random.default_rng(100 + regime)
    scene = random_scene(rng, 3000, scale=0.006)
    scene.opacities[:] = rng.uniform(0.05, 1.0, len(scene.opacities))
    on, off, ref = _checkers(scene, device, **REGIMES[regime])
    n = 3000
    near = np.asarray(scene.means)[rng.integers(0, len(scene.means), n // 2)] + rng.normal(scale=0.01, size=(n // 2, 3))
    centers = np.concatenate([near, rng.uniform(-0.6, 0.6, (n // 2, 3))])
    quats = random_quats(rng, n)
    axes = rng.uniform(0.01, 0.08, (n, 3))
    axes[: n // 4] = axes[: n // 4, :1]  # spheres too
    a = np.asarray(on.collides(centers, quats, axes))
    b = np.asarray(off.collides(centers, quats, axes))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a[::5], np.asarray(ref.collides(centers[::5], quats[::5], axes[::5])))
    assert 0.05 < a.mean() < 0.95


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("regime", [0, 1, 3, 4])
def test_configs_same_with_and_without_hit_bound(device, regime):
    """Per-configuration answers (with and without the RIGID SLACK) equal those without the bound and
    the per-ellipsoid ones; free configurations keep their slack; colliding ones read 0."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(7 + regime)
    wall = rng.uniform(-1.0, 1.0, (5000, 3)) * np.array([0.06, 0.5, 0.4]) + np.array([0.5, 0.0, 0.4])  # a thick wall in front of the arm
    scene = random_scene(rng, len(wall), scale=0.005)
    scene.means[:] = wall
    scene.opacities[:] = rng.uniform(0.05, 1.0, len(wall))
    on, off, ref = _checkers(scene, device, **REGIMES[regime])
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((400, robot.dof)) * (lim[:, 1] - lim[:, 0])
    ws_on, ws_off = on.workspace(), off.workspace()
    h_on = np.array(on.collides_configs(robot, q, out=ws_on))
    h_off = np.array(off.collides_configs(robot, q, out=ws_off))
    np.testing.assert_array_equal(h_on, h_off)
    np.testing.assert_array_equal(h_on, np.asarray(off.collides_robot(robot, q)).any(-1))
    np.testing.assert_array_equal(h_on[:30], np.asarray(ref.collides_robot(robot, q[:30])).any(-1))
    assert 0.1 < h_on.mean() < 0.9
    target = np.full(robot.n_ellipsoids, 0.01)
    hs_on, s_on = (np.array(x) for x in on.collides_configs_slack(robot, q, out=ws_on, rigid_target=target))
    hs_off, s_off = (np.array(x) for x in off.collides_configs_slack(robot, q, out=ws_off, rigid_target=target))
    np.testing.assert_array_equal(hs_on, h_on)
    np.testing.assert_array_equal(hs_off, h_on)
    np.testing.assert_array_equal(s_on[~h_on], s_off[~h_on])
    assert np.all(s_on[h_on] == 0)
    # the general path (no workspace) agrees too
    np.testing.assert_array_equal(np.asarray(on.collides_configs(robot, q)), h_on)
