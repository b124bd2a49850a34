"""The Go2 base planner's structured samples and the SE(2) route to the kitchen."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest


@pytest.fixture(scope="module")
def apartment():
    from splatplan.tasks._common import base_terrain, load_task_scene
    from splatplan.tasks.base import BaseConfig, load_go2

    cfg = BaseConfig()
    return load_go2(), load_task_scene("apartment", n_sigma=cfg.n_sigma, terrain=base_terrain(cfg))


def test_primitives_drive_in_their_directions(apartment):
    from splatplan.planners.dynamics import PlanarBase
    from splatplan.tasks.base import BaseConfig, _BasePlanner

    robot, ts = apartment
    cfg = replace(BaseConfig(), n_directions=8, n_knots=6)
    x = np.array([-2.0, 0.5, 0.7])
    goal = np.array([-2.0, -1.5])  # straight below
    p = _BasePlanner(PlanarBase(robot), cfg, np.asarray(robot.velocity_limits), None, goal)
    knots = p.primitives(x)
    assert knots.shape == (8 * 4, cfg.n_knots, 3)
    ev = p.evaluate(x, np.clip(knots, -p.vmax, p.vmax))
    end = ev["states"][:8, -1, :2] - x[:2]  # straight drives
    th = np.arctan2(goal[1] - x[1], goal[0] - x[0]) + 2 * np.pi * np.arange(8) / 8
    cosang = np.sum(end * np.stack([np.cos(th), np.sin(th)], 1), axis=1) / np.linalg.norm(end, axis=1)
    assert np.all(cosang > 0.9)  # each goes roughly its way while turning to face it (the spline bends the turning ones)
    assert ev["dist"][0].min() < 0.5 * np.linalg.norm(goal - x[:2])  # the goal-bearing drive passes close to the goal


def test_route_reaches_the_kitchen_quickly(apartment):
    from splatplan.tasks.base import plan_route

    robot, ts = apartment
    route = plan_route(robot, ts.checker, np.array([-2.3, -0.6, 0.0]), (2.985, -1.755), time_budget_s=25.0)
    assert route is not None and np.allclose(route[-1, :2], [2.985, -1.755], atol=0.11)
    assert route[:, 0].max() > 1.0
