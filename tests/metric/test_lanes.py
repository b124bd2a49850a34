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
    bad = many_ck.query(wp.array(c.astype(np.float32), dtype=wp.vec3, device=many_ck.device), semi_axes=(0.02, 0.02, 0.02))
    got = {f: np.asarray(v.numpy()) for f, v in bad.as_dict().items()}
    assert np.isnan(got["min_s2"][7]) and got["n_colliding"][7] == -1 and got["in_collision"][7]
    ref = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(lanes=1)).query(np.delete(c, 7, 0), semi_axes=(0.02, 0.02, 0.02))
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
