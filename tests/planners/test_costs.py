"""Cost objects: they compose to the pre-refactor MPPI cost; goal pose, joint limits, terminal;
dynamics built from a Robot."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners import (
    MPPI, CollisionCost, ControlEffortCost, CostWeights, GoalPoseCost, HolonomicPoint, JointIntegrator, JointLimitCost, MPPIConfig, PlanarBase,
    Rollout, StateCost, TerminalCost, total_cost,
)  # fmt: skip

from .scenes import make_checker, make_scene

GOAL = np.array([0.15, 0.0, 0.06])


@pytest.fixture(scope="module")
def checker():
    return make_checker(make_scene([((-0.03, -0.04, 0.0), (0.03, 0.06, 0.12))]), n_sigma=1.0)


def _cfg(**kw):
    base = dict(n_samples=64, horizon=12, n_knots=5, dt=0.1, noise_sigma=0.1, n_iters=1, w_collision=2.0, w_hit=5.0,
                w_task=0.7, w_control=0.3, w_terminal=1.5, seed=0)  # fmt: skip
    base.update(kw)
    names = {f.name for f in dataclasses.fields(CostWeights)}
    return MPPIConfig(**{k: v for k, v in base.items() if k not in names}), CostWeights(**{k: v for k, v in base.items() if k in names})


def task(s):
    return np.linalg.norm(s - GOAL, axis=-1)  # (K, T)


def terminal(xt):
    return 3.0 * np.linalg.norm(xt[:, :2] - GOAL[:2], axis=-1)  # (K,)


def test_costs_compose_to_the_old_mppi_cost(checker):
    cfg, w = _cfg()
    dyn = HolonomicPoint()
    mppi = MPPI(dyn, checker, cfg, task_cost=task, terminal_cost=terminal, weights=w)
    rng = np.random.default_rng(0)
    knots = rng.normal(scale=0.2, size=(cfg.n_samples, cfg.n_knots, 3))
    x0 = np.array([-0.12, 0.0, 0.06])
    ev = mppi.evaluate(x0, knots)
    total, terms, states, controls, res = ev.total, ev.terms, ev.states, ev.controls, ev.query
    # the pre-refactor formula, by hand
    c, q, a = dyn.link_poses(states)
    ref = checker.with_config(s2_cap=w.collision_s2_cap).query(c, q, a)
    k = cfg.n_samples
    old = (w.w_collision * ref.cost.reshape(k, -1).astype(np.float64).sum(1) + w.w_hit * ref.in_collision.reshape(k, -1).sum(1)
           + w.w_task * task(states).sum(1) + w.w_control * np.sum(controls**2, axis=(1, 2)) * cfg.dt
           + w.w_terminal * terminal(states[:, -1]))  # fmt: skip
    assert ref.in_collision.any() and not ref.in_collision.all()  # both kinds of samples
    np.testing.assert_allclose(total, old, rtol=1e-9, atol=1e-9)
    assert set(terms) == {"collision", "hit", "task", "control", "terminal"}
    np.testing.assert_array_equal(res.in_collision, ref.in_collision)
    # the same objective as an explicit list of cost objects
    costs = [CollisionCost(checker, dyn, weight=w.w_collision, hit_weight=w.w_hit, s2_cap=w.collision_s2_cap),
             StateCost(task, w.w_task), ControlEffortCost(w.w_control), TerminalCost(terminal, w.w_terminal)]  # fmt: skip
    explicit = MPPI(dyn, checker, cfg, costs=costs)
    total2 = explicit.evaluate(x0, knots).total
    np.testing.assert_allclose(total2, old, rtol=1e-9, atol=1e-9)
    roll = Rollout(states, controls, cfg.dt)
    t3, _ = total_cost(costs, roll)
    np.testing.assert_allclose(t3, old, rtol=1e-9, atol=1e-9)
    assert any(k[0] == "collision_query" for k in roll.cache if isinstance(k, tuple))  # computed once, shared


def test_goal_pose_and_joint_limit_costs():
    robots = pytest.importorskip("splatplan.robots")
    robot = robots.load_robot("panda")
    q = np.stack([robot.q_default, robot.q_default + 0.3])[:, None, :].repeat(2, axis=1)  # (K=2, T=2, 7)
    poses = robot.link_poses(q)
    hand = robot.link_names.index("panda_hand")
    p_goal = poses[0, 0, hand, :3, 3]
    from splatplan.scenes.splats import rotmat_to_quat

    quat = rotmat_to_quat(poses[0, 0, hand, :3, :3])
    roll = Rollout(q, np.zeros_like(q), 0.1)
    cost = GoalPoseCost(robot, position=p_goal, quat=quat, link="panda_hand", orientation_weight=0.5, terminal_factor=1.0)(roll)
    assert cost[0] == pytest.approx(0.0, abs=1e-6) and cost[1] > 0.05
    # a point / base goal read from the state
    base = GoalPoseCost(position=(1.0, 0.0), state_dims=(0, 1))(Rollout(np.zeros((3, 4, 3)), np.zeros((3, 4, 3)), 0.1))
    np.testing.assert_allclose(base, 4.0)
    with pytest.raises(SplatplanError, match="no link"):
        GoalPoseCost(robot, position=p_goal, link="nope")
    lim = JointLimitCost(robot, weight=1.0)
    inside = Rollout(robot.q_default[None, None], np.zeros((1, 1, 7)), 0.1)
    outside_q = robot.q_default.copy()
    outside_q[3] = 0.5  # joint 4's upper limit is -0.0698
    assert lim(inside)[0] == 0.0
    assert lim(Rollout(outside_q[None, None], np.zeros((1, 1, 7)), 0.1))[0] == pytest.approx((0.5 + 0.0698) ** 2, rel=1e-3)


def test_dynamics_from_a_robot():
    robots = pytest.importorskip("splatplan.robots")
    panda = robots.load_robot("panda")
    dyn = JointIntegrator(panda)
    assert dyn.state_dim == dyn.control_dim == 7
    u = np.full((2, 50, 7), 10.0)  # far above the velocity limits
    s = dyn.rollout(panda.q_default, u, 0.01)
    step = np.diff(np.concatenate([np.broadcast_to(panda.q_default, (2, 1, 7)), s], axis=1), axis=1)
    assert np.all(step <= panda.velocity_limits * 0.01 + 1e-12)
    assert np.all(s <= panda.joint_limits[:, 1] + 1e-12)
    c, q, a = dyn.link_poses(s)
    assert c.shape == (2, 50, panda.n_ellipsoids, 3)
    go2 = robots.load_robot("go2")
    base = PlanarBase(go2)
    out = base.rollout(np.zeros(3), np.array([[[0.5, 0.0, 0.0]] * 10]), 0.1)
    np.testing.assert_allclose(out[0, -1], [0.5, 0.0, 0.0], atol=1e-12)  # body x at yaw 0 = world x
    out = base.rollout(np.array([0.0, 0.0, np.pi / 2]), np.array([[[0.5, 0.0, 0.0]] * 10]), 0.1)
    np.testing.assert_allclose(out[0, -1], [0.0, 0.5, np.pi / 2], atol=1e-12)  # ... and world y at yaw 90 deg
    assert base.link_poses(out)[0].shape == (1, 10, go2.n_ellipsoids, 3)
    with pytest.warns(DeprecationWarning, match="height="):
        assert PlanarBase(0.05).height == 0.05  # the old positional height still works, deprecated (0.3.0)
    point = HolonomicPoint(robots.load_robot("sphere:0.02"))
    assert point.link_poses(np.zeros((1, 1, 3)))[2][0, 0] == pytest.approx(0.02)
