"""CELL BOXES of the collision-only kernels: the per-cell boxes hold their cells' means, the bound
is below the squared scaling distance of every point of its box (and equals its numpy twin), and
every answer and slack is the same with and without the boxes (per ellipsoid and per configuration,
every n_sigma regime)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan._warp import wp as _wp
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.reference import cell_s2_lb_ref
from splatplan.metric.tiers import cell_boxes
from splatplan.metric.wp_metric import TierConfig
from splatplan.metric.wp_metric_kernel import cell_s2_lb_kernel
from splatplan.scenes.splats import quat_to_rotmat

from .conftest import COLLIDE_REGIMES, DEVICES, near_surface_links, option_pair, plane_walls, random_quats, random_scene

wp = _wp()


def test_cell_boxes_hold_their_cells():
    rng = np.random.default_rng(0)
    for trial in range(20):
        counts = rng.integers(0, 6, int(rng.integers(1, 40)))  # empty cells too
        counts[rng.random(len(counts)) < 0.3] = 0
        starts = np.concatenate([[0], np.cumsum(counts)])
        if trial % 2:  # two tiers: the first table's end entry, then the second's cells
            c2 = rng.integers(0, 5, 7)
            starts = np.concatenate([starts, starts[-1] + np.cumsum(np.concatenate([[0], c2]))])
        n = int(starts[-1])
        means = rng.normal(size=(n, 3)).astype(np.float32)
        lo, hi = cell_boxes(means, starts)
        assert lo.shape == hi.shape == (len(starts), 3)
        for k in range(len(starts) - 1):
            a, b = int(starts[k]), int(starts[k + 1])
            if b > a:
                np.testing.assert_array_equal(lo[k], means[a:b].min(axis=0))
                np.testing.assert_array_equal(hi[k], means[a:b].max(axis=0))


def _links_and_boxes(rng, n: int):
    c = rng.uniform(-1.0, 1.0, (n, 3))
    rot = quat_to_rotmat(random_quats(rng, n))
    ax = rng.uniform(0.01, 0.2, (n, 3))
    ctr = c + rng.normal(scale=0.2, size=(n, 3))
    half = rng.uniform(0.0, 0.05, (n, 3)) * (rng.random((n, 3)) < 0.8)  # flat boxes too
    return c, rot, ax, ctr - half, ctr + half


@pytest.mark.parametrize("device", DEVICES)
def test_bound_is_below_every_point_and_matches_numpy_twin(device):
    rng = np.random.default_rng(1)
    n = 2000
    c, rot, ax, lo, hi = _links_and_boxes(rng, n)
    out = wp.zeros(n, dtype=wp.float32, device=device)
    arr = lambda x, t: wp.array(np.asarray(x, np.float32), dtype=t, device=device)  # noqa: E731
    wp.launch(cell_s2_lb_kernel, dim=n, inputs=[arr(c, wp.vec3), arr(rot, wp.mat33), arr(ax, wp.vec3), arr(lo, wp.vec3), arr(hi, wp.vec3), out], device=device)
    got = out.numpy().astype(np.float64)
    ref = cell_s2_lb_ref(c, rot, ax, lo, hi)
    err = np.abs(got - ref) / (1.0 + ref)
    assert err.max() <= 5e-3, (err.max(), got[err.argmax()], ref[err.argmax()])  # (the kernel pads its box by ~3e-5: ~3e-3 of a 1 cm axis)
    assert np.all(got <= ref * (1 + 1e-5) + 1e-6)  # the pad only lowers it
    # below the squared scaling distance of every point of the box (corners and random points)
    t = rng.random((n, 64, 3))
    t[:, :8] = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])  # the corners
    p = lo[:, None] + t * (hi - lo)[:, None]  # (n, 64, 3)
    u = np.einsum("nik,nmi->nmk", rot, p - c[:, None])  # link frame
    s2 = np.sum((u / ax[:, None]) ** 2, axis=-1).min(axis=1)  # (n,)
    assert np.all(ref <= s2 * (1 + 1e-9) + 1e-12)
    assert np.all(got <= s2 * (1 + 1e-5) + 1e-6)
    assert (ref > 1.0).mean() > 0.3  # far boxes occur (the bound is not vacuous)
    near = s2 < 4.0
    assert np.median(ref[near] / np.maximum(s2[near], 1e-12)) > 0.5  # and reasonably tight


REGIMES = COLLIDE_REGIMES


def _dense_walls(rng, n: int):
    """n small splats on two walls and a tilted plane (dense: many splats per grid cell)."""
    return plane_walls(rng, n, scale=0.002, noise=0.001)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("regime", range(len(REGIMES)))
def test_same_answers_with_and_without_boxes(device, regime):
    rng = np.random.default_rng(60 + regime)
    scene = _dense_walls(rng, 30000)
    on, off = option_pair(scene, device, "collide_cell_boxes", **REGIMES[regime])
    ref = CollisionChecker(scene, config=MetricConfig(**REGIMES[regime]), backend="reference")
    centers, quats, axes = near_surface_links(rng, scene, 2000)
    a = np.asarray(on.collides(centers, quats, axes))
    np.testing.assert_array_equal(a, np.asarray(off.collides(centers, quats, axes)))
    np.testing.assert_array_equal(a[::8], np.asarray(ref.collides(centers[::8], quats[::8], axes[::8])))
    assert 0.02 < a.mean() < 0.95


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("regime", [0, 1, 4])
def test_configs_and_slack_same_with_and_without_boxes(device, regime):
    """Per configuration: the same answers, FREE SLACK and RIGID SLACK with and without the boxes
    (a skipped cell holds only means beyond the scan's cut, which no slack reads)."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(70 + regime)
    wall = rng.uniform(-1.0, 1.0, (40000, 3)) * np.array([0.004, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])  # a dense thin wall
    scene = random_scene(rng, len(wall), scale=0.002)
    scene.means[:] = wall
    on, off = option_pair(scene, device, "collide_cell_boxes", **REGIMES[regime])
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((300, robot.dof)) * (lim[:, 1] - lim[:, 0])
    h_on, s_on = (np.asarray(x) for x in on.collides_configs_slack(robot, q))
    h_off, s_off = (np.asarray(x) for x in off.collides_configs_slack(robot, q))
    np.testing.assert_array_equal(h_on, h_off)
    np.testing.assert_array_equal(s_on, s_off)
    assert 0.05 < h_on.mean() < 0.9
    target = rng.uniform(0.0, 0.03, (len(q), robot.n_ellipsoids))
    hr, sr = (np.asarray(x) for x in on.collides_configs_slack(robot, q, rigid_target=target))
    hr2, sr2 = (np.asarray(x) for x in off.collides_configs_slack(robot, q, rigid_target=target))
    np.testing.assert_array_equal(hr, h_on)
    np.testing.assert_array_equal(hr2, hr)
    np.testing.assert_array_equal(sr, sr2)
    np.testing.assert_array_equal(np.asarray(on.collides_robot(robot, q[:100])), np.asarray(off.collides_robot(robot, q[:100])))
    for ch in (on, off):
        ch.close()


def test_only_dense_tiers_get_boxes():
    """A dense wall's tier gets boxes; a sparse scene's tiers do not (the kernel would not test its
    cells), and with the option off none does."""
    rng = np.random.default_rng(80)
    dense = _dense_walls(rng, 30000)
    sparse = random_scene(rng, 3000, scale=0.01)
    robot_like = (np.zeros((1, 3)), random_quats(rng, 1), np.full((1, 3), 0.03))

    def bases(scene, **tiers):
        ch = CollisionChecker(scene, config=MetricConfig(n_sigma=0.0), device="cpu", tiers=TierConfig(**tiers))
        ch.collides(*robot_like)
        out = [gs.tiers.box_base.numpy().tolist() for gs in ch._impl._gridsets.values()]
        ch.close()
        return out

    assert any(b >= 0 for bs in bases(dense) for b in bs)
    assert all(b < 0 for bs in bases(sparse) for b in bs)
    assert all(b < 0 for bs in bases(dense, collide_cell_boxes=False) for b in bs)
