"""COVER SPHERES of the collision-only kernels: the spheres hold the (scaled) link, the kernel's margin
equals its numpy twin, an elongated link beside a wall is cleared by it (the bound at its centre
cannot), and every answer is the same with and without the test (per ellipsoid and per
configuration, every n_sigma regime)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan._warp import wp as _wp
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.reference import cover_spheres_ref, mean_distance_lb_ref
from splatplan.metric.wp_metric import TierConfig, WarpMetric
from splatplan.metric.wp_metric_kernel import cover_margin_kernel
from splatplan.scenes.splats import quat_to_rotmat

from .conftest import COLLIDE_REGIMES, DEVICES, near_surface_links, option_pair, plane_walls, random_quats, random_scene

wp = _wp()


def _inside_points(rng, n: int, axes: np.ndarray) -> np.ndarray:
    """(n, 3) points of the link frame on and inside the ellipsoid of semi-axes ``axes``."""
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = np.where(rng.random(n) < 0.5, 1.0, rng.random(n) ** (1 / 3))[:, None]  # half on the surface
    return u * r * axes


@pytest.mark.parametrize("s_star", [1.0, 1.7])
def test_spheres_hold_the_scaled_link(s_star):
    rng = np.random.default_rng(0)
    tested = 0
    for trial in range(200):
        axes = rng.uniform(0.01, 0.1, 3)
        if trial % 4 == 0:
            axes[:] = axes[0]  # a sphere: one sphere, the link itself
        rot = quat_to_rotmat(random_quats(rng, 1))[0]
        c = rng.uniform(-1, 1, 3)
        centres, radii = cover_spheres_ref(c, rot, axes, s_star)
        if trial % 4 == 0:
            assert len(radii) == 0  # (no cover for a sphere: its bounding sphere is the link)
            continue
        if len(radii) == 0:
            continue
        assert 2 <= len(radii) <= 4
        tested += 1
        p = c + (_inside_points(rng, 2000, axes) * s_star) @ rot.T  # (n, 3) world
        d = np.linalg.norm(p[:, None] - centres[None], axis=-1) - radii  # (n, K)
        assert np.all(d.min(axis=1) <= 1e-12)
        assert radii.max() < s_star * axes.max()  # each tighter than the bounding sphere
    assert tested > 80


def _grid_of(wm: WarpMetric):
    """The metric's mean-distance grid and its numpy arrays (lb, origin, v, box lo, box hi)."""
    return wm.mean_distance_grid(), wm._dgrid_lb


@pytest.mark.parametrize("device", DEVICES)
def test_kernel_margin_matches_numpy_twin(device):
    rng = np.random.default_rng(1)
    scene = random_scene(rng, 4000, scale=0.003)
    wm = WarpMetric(scene, device=device, tiers=TierConfig(distance_grid_voxels=2**16))
    g, (lb, origin, v, lo, hi) = _grid_of(wm)
    n = 3000
    means = np.asarray(scene.means)
    centers = np.concatenate([means[rng.integers(0, len(means), n // 2)] + rng.normal(scale=0.05, size=(n // 2, 3)),
                              rng.uniform(-0.8, 0.8, (n - n // 2, 3))])  # fmt: skip
    rots = quat_to_rotmat(random_quats(rng, n))
    axes = rng.uniform(0.005, 0.08, (n, 3))
    axes[::7] = axes[::7, :1]  # spheres
    for s_star in (1.0, 1.4):
        out = wp.zeros(n, dtype=wp.float32, device=device)
        wp.launch(cover_margin_kernel, dim=n, device=device,
                  inputs=[g, wp.array(centers.astype(np.float32), dtype=wp.vec3, device=device), wp.array(rots.astype(np.float32), dtype=wp.mat33, device=device),
                          wp.array(axes.astype(np.float32), dtype=wp.vec3, device=device), float(s_star), out])  # fmt: skip
        got = out.numpy().astype(np.float64)
        ref = np.empty(n)
        for i in range(n):
            cs, r = cover_spheres_ref(centers[i], rots[i], axes[i], s_star)
            if len(r) == 0:
                ref[i] = -1.0
                continue
            m = mean_distance_lb_ref(lb, origin, v, lo, hi, cs) - r * 1.0001 - 1e-5 * np.linalg.norm(cs, axis=1)
            ref[i] = m.min() if m.min() > 0 else m[np.argmax(m <= 0)]  # (the kernel stops at the first sphere <= 0)
        pos = (got > 1e-5) & (ref > 1e-5)
        assert np.mean(np.sign(got) == np.sign(ref)) > 0.99  # (a point within float32 rounding of a voxel face may read the neighbour)
        np.testing.assert_allclose(got[pos], ref[pos], atol=2e-5)
        assert 0.1 < np.mean(got > 0) < 0.9


@pytest.mark.parametrize("device", DEVICES)
def test_elongated_link_beside_a_wall_is_cleared(device):
    """A rod 1 cm from a wall of means: the bound at its centre is below its length, so the centre test
    cannot clear it; its cover spheres (radius ~1.2 cm) can."""
    rng = np.random.default_rng(2)
    yz = rng.uniform(-0.4, 0.4, (20000, 2))
    means = np.column_stack([np.zeros(len(yz)), yz])
    scene = random_scene(rng, len(means), scale=0.002)
    scene.means[:] = means
    wm = WarpMetric(scene, device=device, tiers=TierConfig(distance_grid_voxels=2**18))
    g, (lb, origin, v, lo, hi) = _grid_of(wm)
    c = np.array([[0.04, 0.0, 0.0]])
    axes = np.array([[0.01, 0.15, 0.01]])  # long along y, parallel to the wall
    assert mean_distance_lb_ref(lb, origin, v, lo, hi, c)[0] < axes.max()
    out = wp.zeros(1, dtype=wp.float32, device=device)
    wp.launch(cover_margin_kernel, dim=1, device=device,
              inputs=[g, wp.array(c.astype(np.float32), dtype=wp.vec3, device=device), wp.array(np.eye(3, dtype=np.float32)[None], dtype=wp.mat33, device=device),
                      wp.array(axes.astype(np.float32), dtype=wp.vec3, device=device), 1.0, out])  # fmt: skip
    assert out.numpy()[0] > 0
    for cover in (True, False):
        ch = CollisionChecker(scene, n_sigma=0.0, device=device, tiers=TierConfig(collide_cover=cover, distance_grid_voxels=2**18))
        assert not bool(np.asarray(ch.collides(c, np.array([[1.0, 0, 0, 0]]), axes))[0])
        assert bool(np.asarray(ch.collides(c - [0.035, 0, 0], np.array([[1.0, 0, 0, 0]]), axes))[0])  # 5 mm from the wall: the rod's tube holds means


REGIMES = COLLIDE_REGIMES


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("regime", range(len(REGIMES)))
def test_same_answers_with_and_without_cover(device, regime):
    rng = np.random.default_rng(30 + regime)
    scene = plane_walls(rng, 6000, scale=0.003, noise=0.002)
    on, off = option_pair(scene, device, "collide_cover", **REGIMES[regime])
    ref = CollisionChecker(scene, config=MetricConfig(**REGIMES[regime]), backend="reference")
    centers, quats, axes = near_surface_links(rng, scene, 3000)
    a = np.asarray(on.collides(centers, quats, axes))
    np.testing.assert_array_equal(a, np.asarray(off.collides(centers, quats, axes)))
    np.testing.assert_array_equal(a[::6], np.asarray(ref.collides(centers[::6], quats[::6], axes[::6])))
    assert 0.02 < a.mean() < 0.95
    if REGIMES[regime]["n_sigma"] == 0:  # the cover decides some of these links (s* = 1): the test is not vacuous
        lb, origin, v, lo, hi = on._kernels()._dgrid_lb
        rots = quat_to_rotmat(quats)
        near = mean_distance_lb_ref(lb, origin, v, lo, hi, centers) <= axes.max(1)
        cleared = 0
        for i in np.nonzero(near)[0]:
            cs, r = cover_spheres_ref(centers[i], rots[i], axes[i])
            cleared += bool(len(r) and np.all(mean_distance_lb_ref(lb, origin, v, lo, hi, cs) > r * 1.001))
        assert cleared > 20


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("regime", [0, 1, 4])
def test_configs_same_with_and_without_cover(device, regime):
    """Per configuration: the same answers and FREE SLACK with and without the cover; with a RIGID
    SLACK target, the same answers and no slack on a colliding configuration (that the slack holds
    is ``test_collides_configs.test_rigid_slack_holds_near_surfaces``, which runs with the cover on)."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(50 + regime)
    wall = rng.uniform(-1.0, 1.0, (6000, 3)) * np.array([0.01, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])  # a thin wall in front of the arm
    scene = random_scene(rng, len(wall), scale=0.003)
    scene.means[:] = wall
    on, off = option_pair(scene, device, "collide_cover", **REGIMES[regime])
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((400, robot.dof)) * (lim[:, 1] - lim[:, 0])
    h_on, s_on = (np.asarray(x) for x in on.collides_configs_slack(robot, q))
    h_off, s_off = (np.asarray(x) for x in off.collides_configs_slack(robot, q))
    np.testing.assert_array_equal(h_on, h_off)
    np.testing.assert_array_equal(s_on, s_off)
    assert 0.05 < h_on.mean() < 0.9
    target = np.full(robot.n_ellipsoids, 0.01)
    hr, sr = (np.asarray(x) for x in on.collides_configs_slack(robot, q, rigid_target=target))
    np.testing.assert_array_equal(hr, h_on)
    assert np.all(sr[hr] == 0) and np.all(sr >= 0)
