"""Several threads per query in the full kernel (TierConfig.lanes, the CUDA default): the same
outputs as one thread per query, and as the float64 reference, on CPU (and CUDA when present)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan._warp import wp as _wp
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.wp_metric import TierConfig
from splatplan.robots import load_robot

from .conftest import DEVICES, random_quats, random_scene
from .test_kernel_vs_reference import _check_against_reference

FLOATS = ("softmin", "cost")
wp = _wp()


def _same(a, b):
    """Counts, flags and min s2~ exact (a min is order-free); float sums to summation order."""
    for f in ("n_colliding", "in_collision", "min_s2"):
        np.testing.assert_array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), err_msg=f)
    for f in FLOATS:
        np.testing.assert_allclose(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), rtol=2e-5, atol=1e-6, err_msg=f)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("lanes", [2, 3, 8])
@pytest.mark.parametrize("reduce", ["mean", "sum", "max"])
def test_lanes_match_one_thread_and_the_reference(device, lanes, reduce):
    rng = np.random.default_rng(lanes)
    scene = random_scene(rng, 1500)
    b = 400
    centers = rng.uniform(-0.3, 0.3, (b, 3))
    centers[: b // 2] = scene.means[rng.integers(0, len(scene), b // 2)] + rng.normal(0, 0.01, (b // 2, 3))
    quats, axes = random_quats(rng, b), rng.uniform(0.005, 0.06, (b, 3))
    axes[:50, 0] = 0.2  # elongated links: clipped rows
    cfg = MetricConfig(n_sigma=1.0, cost_reduce=reduce)
    one = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(lanes=1)).query(centers, quats, axes)
    many_ck = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(lanes=lanes))
    assert many_ck._impl.lanes == lanes
    many = many_ck.query(centers, quats, axes)
    _same(many, one)
    _check_against_reference(scene, centers, quats, axes, cfg, many, many_ck.collides(centers, quats, axes))
    # an invalid query (device input, not validated on the host) reads in collision with NaN distances
    c = centers.copy()
    c[7] = np.nan
    bad = many_ck.query(wp.array(c.astype(np.float32), dtype=wp.vec3, device=many_ck.device), None, (0.02, 0.02, 0.02))
    got = {f: np.asarray(v.numpy()) for f, v in bad.as_dict().items()}
    assert np.isnan(got["min_s2"][7]) and got["n_colliding"][7] == -1 and got["in_collision"][7]
    ref = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(lanes=1)).query(np.delete(c, 7, 0), None, (0.02, 0.02, 0.02))
    _same(_take_dict(got, np.arange(b) != 7), ref)


def _take_dict(d, m):
    from splatplan.metric.checker import QueryResult

    return QueryResult(**{f: v[m] for f, v in d.items()})


@pytest.mark.parametrize("device", DEVICES)
def test_panda_query_robot_with_lanes(device):
    robot = load_robot("panda")
    rng = np.random.default_rng(3)
    scene = random_scene(rng, 3000, scale=0.01)
    scene.means[:] = scene.means * 2.0 + np.array([0.4, 0.0, 0.3])  # around the arm's workspace
    q = rng.uniform(robot.joint_limits[:, 0], robot.joint_limits[:, 1], (64, robot.dof))
    one = CollisionChecker(scene, n_sigma=1.0, device=device, tiers=TierConfig(lanes=1)).query_robot(robot, q)
    many = CollisionChecker(scene, n_sigma=1.0, device=device, tiers=TierConfig(lanes=4)).query_robot(robot, q)
    assert np.asarray(one.n_colliding).sum() > 0
    _same(many, one)


def test_default_lanes_per_device():
    scene = random_scene(np.random.default_rng(0), 100)
    assert CollisionChecker(scene, device="cpu")._impl.lanes == 1
    with pytest.raises(ValueError, match="lanes"):
        CollisionChecker(scene, device="cpu", tiers=TierConfig(lanes=0))._impl.lanes


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("lanes", [1, 8])
def test_group_links_changes_only_the_order(device, lanes):
    """TierConfig.group_links sorts a robot batch by ellipsoid: every output is the same, bit for bit
    (each query sums its splats in the same order whichever thread runs it)."""
    rng = np.random.default_rng(5)
    scene = random_scene(rng, 3000, scale=0.01)
    scene.means[:] = scene.means * 2.0 + np.array([0.4, 0.0, 0.3])  # around the arm's workspace
    robot = load_robot("panda")
    q = np.clip(robot.q_default + rng.normal(0, 0.4, (160, robot.dof)), robot.joint_limits[:, 0], robot.joint_limits[:, 1])  # 1,760 ellipsoids
    cfg = MetricConfig(n_sigma=1.0)
    plain = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(lanes=lanes)).query_robot(robot, q)
    grouped_ck = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(lanes=lanes, group_links=True))
    grouped = grouped_ck.query_robot(robot, q)
    assert len(q) * robot.n_ellipsoids >= grouped_ck._impl.tiers.sort_min_batch  # the batch is sorted
    assert np.asarray(plain.n_colliding).sum() > 0
    for f in ("min_s2", "n_colliding", "in_collision", "softmin", "cost"):
        np.testing.assert_array_equal(np.asarray(getattr(grouped, f)), np.asarray(getattr(plain, f)), err_msg=f)


def test_group_keys_put_the_ellipsoid_above_the_morton_code():
    from splatplan.metric.wp_metric_kernel import morton_keys_kernel

    rng = np.random.default_rng(0)
    b, period = 2000, 11
    c = wp.array(rng.uniform(0, 1, (b, 3)).astype(np.float32), dtype=wp.vec3, device="cpu")
    keys, vals = wp.empty(2 * b, dtype=wp.int32, device="cpu"), wp.empty(2 * b, dtype=wp.int32, device="cpu")
    shift = -(-(period - 1).bit_length() // 3)
    wp.launch(morton_keys_kernel, dim=b, inputs=[c, wp.vec3(0.0, 0.0, 0.0), wp.vec3(1023.0, 1023.0, 1023.0), keys, vals, period, shift], device="cpu")
    k = keys.numpy()[:b]
    assert k.max() < 2**30
    np.testing.assert_array_equal(k >> (3 * (10 - shift)), np.arange(b) % period)
    wp.utils.radix_sort_pairs(keys, vals, b, 0, 30)
    order = vals.numpy()[:b]
    assert sorted(order) == list(range(b))
    assert np.all(np.diff(order % period) >= 0)  # grouped by ellipsoid
