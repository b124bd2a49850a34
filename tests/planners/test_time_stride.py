"""CollisionCost(time_stride="auto"): the largest stride whose evaluated steps are at most max_gap_m apart."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners import MPPI, CollisionCost, CostWeights, HolonomicPoint, JointIntegrator, MPPIConfig, PlanarBase
from splatplan.planners.costs import Rollout
from splatplan.planners.mppi import collision_stride_value, joint_speed_bound
from splatplan.robots import load_robot

from .scenes import make_checker, make_scene


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


@pytest.fixture(scope="module")
def checker():
    return make_checker(make_scene([((0.25, -0.15, 0.45), (0.4, 0.15, 0.75))], spacing=0.03))


def test_auto_stride_rule(panda, checker):
    v = np.full(panda.dof, 0.1)
    cost = CollisionCost(checker, panda, time_stride="auto", max_gap_m=0.05, speed_bound=v)
    m = float(panda.motion_bound @ v)  # metres per second of motion at most
    assert cost.step_motion(0.01) == pytest.approx(m * 0.01)
    for dt in (0.001, 0.005, 0.01, 0.05, 1.0):
        s = cost.stride(dt, 1000)
        assert s >= 1
        if s > 1:
            assert s * m * dt <= 0.05 * (1 + 1e-9)  # evaluated steps at most max_gap apart ...
        assert (s + 1) * m * dt > 0.05 or s == 1000  # ... and the stride is the largest such
    assert cost.stride(1e-6, 20) == 20  # never beyond the horizon
    # default gap: half the smallest semi-axis of the moving ellipsoids
    d = CollisionCost(checker, panda, time_stride="auto", speed_bound=v)
    assert d.max_gap_m == pytest.approx(0.5 * panda.semi_axes[~panda.static_ellipsoids].min())


def test_auto_stride_bounds_the_motion_of_every_point(panda, checker):
    """On real rollouts, no ellipsoid point moves more than max_gap between evaluated steps."""
    rng = np.random.default_rng(0)
    dt, gap = 0.0005, 0.03  # at full speed a Panda point moves <= 5.4 mm per step: stride 5
    dyn = JointIntegrator(panda)
    cost = CollisionCost(checker, dyn, time_stride="auto", max_gap_m=gap)
    np.testing.assert_allclose(cost.speed_bound, panda.velocity_limits)  # from the integrator's clip
    u = rng.uniform(-1, 1, (8, 40, panda.dof)) * panda.velocity_limits * 3  # saturating commands
    states = dyn.rollout(panda.q_default, u, dt)
    steps = cost.steps(40, dt)
    assert cost.stride(dt, 40) == 5 and steps[-1] == 39 and len(steps) == 8
    cc, rr = panda.ellipsoid_frames(states[:, steps])  # (8, S, E, 3) centres, (8, S, E, 3, 3)
    # the points of ellipsoid e: centre + R (a * unit vector); check the centres and the 6 axis tips
    pts = [cc] + [cc + s * rr[..., :, k] * panda.semi_axes[:, k, None] for k in range(3) for s in (-1, 1)]
    for p in pts:
        move = np.linalg.norm(np.diff(p, axis=1), axis=-1)
        assert move.max() <= gap * (1 + 1e-9)
    roll = Rollout(states, u, dt)
    value = cost.evaluate(roll)
    assert value.query.min_s2.shape == (8, len(steps), panda.n_ellipsoids)
    np.testing.assert_allclose(value.terms["hit"], cost.stride(dt, 40) * 10.0 * value.query.in_collision.reshape(8, -1).sum(1))  # sums scaled by the stride


def test_auto_stride_is_one_when_a_step_moves_more_than_the_gap(panda, checker):
    cost = CollisionCost(checker, JointIntegrator(panda), time_stride="auto")
    assert cost.stride(0.05, 32) == 1  # the Panda moves up to ~0.5 m per 0.05 s step at full speed
    np.testing.assert_array_equal(cost.steps(32, 0.05), np.arange(32))


def test_speed_bounds_of_the_dynamics(panda, checker):
    go2 = load_robot("go2")
    cost = CollisionCost(checker, PlanarBase(go2), time_stride="auto")
    v = go2.velocity_limits
    np.testing.assert_allclose(cost.speed_bound, [np.hypot(v[0], v[1])] * 2 + [v[2]])
    with pytest.raises(SplatplanError, match="speed_bound"):
        CollisionCost(checker, HolonomicPoint(load_robot("sphere:0.02")), time_stride="auto")
    with pytest.raises(SplatplanError, match="auto"):
        CollisionCost(checker, panda, time_stride="sometimes")
    # MPPI: the control bounds tighten the joint speed
    dyn = JointIntegrator(panda)
    np.testing.assert_allclose(joint_speed_bound(dyn, -1.0, 1.0), np.minimum(panda.velocity_limits, 1.0))
    mppi = MPPI(dyn, checker, MPPIConfig(n_samples=4, horizon=8, n_knots=4, dt=0.001, u_min=-0.5, u_max=0.5), weights=CostWeights(collision_stride="auto", collision_max_gap_m=0.01))
    col = mppi.costs[0]
    np.testing.assert_allclose(col.speed_bound, 0.5)
    assert col.max_gap_m == 0.01 and col.stride(0.001, 8) == int(0.01 // (0.5 * panda.motion_bound.sum() * 0.001))
    _, info = mppi.step(panda.q_default)
    assert info.nominal_min_s2.shape == (8, panda.n_ellipsoids)  # every step reported for the nominal


def test_config_validates_the_stride():
    with pytest.raises(SplatplanError):
        CostWeights(collision_stride=0).validate()
    with pytest.raises(SplatplanError):
        CostWeights(collision_stride="often").validate()
    with pytest.raises(SplatplanError):
        CostWeights(collision_max_gap_m=-1.0).validate()
    assert collision_stride_value(CostWeights(collision_stride="3").validate().collision_stride) == 3
