"""The Go2 base planner's structured samples and the SE(2) route to the kitchen."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def apartment():
    from splatplan.tasks._common import base_terrain, load_task_scene
    from splatplan.tasks.base import BaseConfig, load_go2

    cfg = BaseConfig()
    return load_go2(), load_task_scene("apartment", n_sigma=cfg.n_sigma, terrain=base_terrain(cfg))


def test_primitives_drive_in_their_directions(apartment):
    from splatplan.planners import MPPI, MPPIConfig, PlanarBase
    from splatplan.planners.drive import DriveGoalCost, StructuredDrives

    robot, ts = apartment
    x = np.array([-2.0, 0.5, 0.7])
    goal = np.array([-2.0, -1.5])  # straight below
    vmax = tuple(np.asarray(robot.velocity_limits))
    goal_cost = DriveGoalCost(goal)
    drives = StructuredDrives(goal_cost, n_directions=8)
    mppi = MPPI(PlanarBase(robot), None, MPPIConfig(n_samples=64, horizon=20, n_knots=6, dt=0.2, n_iters=1, clamped_spline=False, u_min=tuple(-v for v in vmax), u_max=vmax),
                costs=[goal_cost], sampler=drives)  # fmt: skip
    drives.bind(mppi.spline.basis, mppi.config.dt)
    knots = drives.primitives(x)
    assert knots.shape == (8 * 4, 6, 3)
    ev = mppi.evaluate(x, mppi.clip(knots))
    end = ev.states[:8, -1, :2] - x[:2]  # straight drives
    th = np.arctan2(goal[1] - x[1], goal[0] - x[0]) + 2 * np.pi * np.arange(8) / 8
    cosang = np.sum(end * np.stack([np.cos(th), np.sin(th)], 1), axis=1) / np.linalg.norm(end, axis=1)
    assert np.all(cosang > 0.9)  # each goes roughly its way while turning to face it (the spline bends the turning ones)
    assert ev.values["goal_distance"][0].min() < 0.5 * np.linalg.norm(goal - x[:2])  # the goal-bearing drive passes close to the goal
    # one MPC step: the drives and the Gaussian samples (K = 64 - 32) reach MPPI through the strategy
    u, info = mppi.step(x)
    assert info.costs.shape == (64,) and u.shape == (3,) and drives.step_i == 0 and drives.mode == "goal"


def test_route_reaches_the_kitchen_quickly(apartment):
    from splatplan.planners.route import plan_route

    robot, ts = apartment
    route = plan_route(robot, ts.checker, np.array([-2.3, -0.6, 0.0]), (2.985, -1.755), time_budget_s=25.0)
    assert route is not None and np.allclose(route[-1, :2], [2.985, -1.755], atol=0.11)
    assert route[:, 0].max() > 1.0
