"""MPPIConfig.prune_margin: hopeless samples are not collision-checked to the end, and the update
is the unpruned one to float64 rounding (a weight below exp(-margin) of the best's cannot move it)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.eval.arm import START_Q
from splatplan.metric import CollisionChecker
from splatplan.planners import MPPI, CollisionCost, ControlEffortCost, GoalPoseCost, JointIntegrator, JointLimitCost, MPPIConfig

robots = pytest.importorskip("splatplan.robots")


@pytest.fixture(scope="module")
def arm():
    from splatplan.scenes.builtin import build_builtin
    from splatplan.scenes.builtin.tabletop import TARGET_REGION
    from splatplan.scenes.filters import filter_floaters

    robot = robots.load_robot("panda")
    scene, _ = filter_floaters(build_builtin("tabletop", seed=0, n_splats=20_000)[0])
    return robot, CollisionChecker(scene, n_sigma=1.0), 0.5 * (TARGET_REGION[0] + TARGET_REGION[1])


def _mppi(arm, prune, stride=1):
    robot, checker, target = arm
    cfg = MPPIConfig(n_samples=48, horizon=16, n_knots=5, dt=0.05, n_iters=1, noise_sigma=0.4, temperature=0.05,
                     u_min=-1.0, u_max=1.0, seed=3, prune_margin=prune)  # fmt: skip
    dyn = JointIntegrator(robot)
    costs = [CollisionCost(checker, dyn, weight=1.0, hit_weight=10.0, s2_cap=2.0, time_stride=stride), GoalPoseCost(robot, position=target, link="panda_hand_tcp", terminal_factor=4.0),
             ControlEffortCost(0.01), JointLimitCost(robot, weight=100.0)]  # fmt: skip
    return MPPI(dyn, checker, cfg, costs=costs), dyn


@pytest.mark.parametrize("stride", [1, 3])
def test_pruned_batch_costs_are_exact_or_hopeless_lower_bounds(arm, stride):
    full, _ = _mppi(arm, None, stride)
    pruned, _ = _mppi(arm, 40.0, stride)
    robot = arm[0]
    rng = np.random.default_rng(0)
    knots = np.clip(rng.normal(0, 0.6, (48, 5, robot.dof)), -1, 1)
    x = np.asarray(START_Q, dtype=float)  # the arm study's start, gripper in front of the bin wall near the table
    ev_full, ev_pr = full.evaluate(x, knots), pruned.evaluate(x, knots)
    t_full, terms_full, t_pr, terms_pr = ev_full.total, ev_full.terms, ev_pr.total, ev_pr.terms
    cut = float(t_full.min()) + 40.0 * 0.05
    kept = t_pr >= t_full - 1e-9 * np.abs(t_full)  # complete (equal) ...
    np.testing.assert_allclose(t_pr[kept], t_full[kept], rtol=1e-12)
    low = ~kept  # ... or a lower bound of a hopeless sample
    assert np.all(t_pr[low] <= t_full[low]) and np.all(t_full[low] > cut)
    assert ev_pr.n_pruned >= int(low.sum())  # a pruned sample whose later chunks were free reads exact
    assert ev_pr.n_pruned > 0  # the table makes most random samples hopeless
    assert int(np.argmin(t_pr)) == int(np.argmin(t_full)) and t_pr.min() == pytest.approx(t_full.min(), rel=1e-12)
    for name in terms_full:
        assert terms_pr[name].shape == (48,)


def test_pruned_mpc_gives_the_same_controls(arm):
    (a, dyn), (b, _) = _mppi(arm, None), _mppi(arm, 40.0)
    x = xa = np.asarray(START_Q, dtype=float)
    n = 0
    for _ in range(4):
        ua, _ = a.step(xa)
        ub, info = b.step(x)
        n += info.n_pruned
        np.testing.assert_allclose(ub, ua, rtol=0, atol=1e-10)
        xa = x = dyn.rollout(x, ua[None, None, :], 0.05)[0, 0]
    assert n > 0


def test_prune_options_are_checked():
    for kw in ({"prune_margin": 0.0}, {"prune_margin": float("nan")}, {"prune_chunks": 1}, {"prune_probe": 0}):
        with pytest.raises(SplatplanError, match="prune"):
            MPPIConfig(**kw).validate()
