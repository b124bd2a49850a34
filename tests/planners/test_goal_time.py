"""GoalTimeMPC's goal search and route: the knots fitted to a path follow it, and a goal behind a wall
is reached around it when the initial plan searches the goal first and a planner's path seeds the plan."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.planners import MPPI, CollisionCost, HolonomicPoint, MPPIConfig, RRTConfig, UntilGoalCost, plan
from splatplan.planners.cost_base import Cost, CostValue
from splatplan.planners.goal_time import GoalTimeMPC, GoalTimeSchedule
from splatplan.robots import load_robot

from .scenes import make_checker, make_scene

START = np.array([-0.15, 0.0, 0.06])
GOAL = np.array([0.15, 0.0, 0.06])
VMAX = np.array([0.3, 0.3, 0.0])


class GoalAtTime(Cost):
    """100 x squared distance of the state at the goal time to GOAL; reports it raw as ``goal_raw``."""

    name = "goal"

    def evaluate(self, rollout) -> CostValue:
        g = rollout.states.shape[1] - 1 if rollout.goal_step is None else int(rollout.goal_step)
        d2 = np.sum((rollout.states[:, g] - GOAL) ** 2, axis=-1)
        return CostValue({"goal": 100.0 * d2}, {"goal_raw": d2})

    def terms(self, rollout):
        return self.evaluate(rollout).terms

    def __call__(self, rollout):
        return self.terms(rollout)["goal"]


@pytest.fixture(scope="module")
def checker():
    # a wall across the straight line from START to GOAL, open around its ends
    return make_checker(make_scene([((-0.01, -0.25, 0.0), (0.01, 0.25, 0.12))]), n_sigma=1.0)


def _mppi(costs):
    cfg = MPPIConfig(n_samples=64, horizon=30, n_knots=8, dt=0.1, temperature=0.05, noise_sigma=0.1, n_iters=1, u_min=tuple(-VMAX), u_max=tuple(VMAX), seed=0, report_nominal=True)
    return MPPI(HolonomicPoint(), None, cfg, costs=costs)


SCHEDULE = GoalTimeSchedule(plan_iters=20, plan_starts=2, plan_start_iters=15, plan_start_refine=0, refine_plan_iters=0, refine_iters=0, noise_cost_ref=0.0, route_iters=5)


def test_fit_path_follows_a_path_with_a_corner():
    run = GoalTimeMPC(_mppi([GoalAtTime()]), SCHEDULE, VMAX, "goal_raw")
    path = np.array([START, [-0.15, 0.15, 0.06], [0.1, 0.15, 0.06]])
    goal = 24
    knots = run.fit_path(START, path, goal)
    assert knots.shape == (8, 3) and np.all(np.abs(knots) <= VMAX + 1e-12)
    states = run.dyn.rollout(START, run.mppi.spline(knots[None]), 0.1)[0]  # (T, 3)
    assert np.linalg.norm(states[goal] - path[-1]) < 0.01  # ends where the path ends, at the goal step
    # every rollout state lies near the path (distance to the polyline)
    a, b = path[:-1], path[1:]
    t = np.clip(np.einsum("sij,ij->si", states[:, None] - a[None], b - a) / np.sum((b - a) ** 2, axis=1), 0, 1)
    dist = np.min(np.linalg.norm(states[:, None] - (a + t[..., None] * (b - a)), axis=-1), axis=1)
    assert dist.max() < 0.03


def test_goal_search_and_route_reach_a_goal_behind_a_wall(checker):
    robot = load_robot("sphere:0.015")
    collision = CollisionCost(checker, robot, weight=1.0, hit_weight=10.0)
    full = _mppi([UntilGoalCost([collision]), GoalAtTime()])
    search = _mppi([GoalAtTime()])  # the goal search leaves the path's collision cost out
    calls = []

    def route(a, b):
        calls.append((a.copy(), b.copy()))
        res = plan(checker, a, b, robot=robot, refine=False, rrt_config=RRTConfig(box_lo=(-0.35, -0.35, 0.06), box_hi=(0.35, 0.35, 0.06)))
        return res.path if res.success else None

    run = GoalTimeMPC(full, SCHEDULE, VMAX, "goal_raw", search=search, route=route)
    states, trace = run.execute(START.copy())
    states = np.asarray(states)
    assert run.kept_search and run.route_outcome == "routed" and len(calls) == 1
    np.testing.assert_allclose(calls[0][0], START)
    assert np.linalg.norm(calls[0][1] - GOAL) < 0.05  # the search found the goal before the route
    assert np.linalg.norm(states[-1] - GOAL) < 0.02
    assert not checker.collides(states, None, (0.015, 0.015, 0.015)).any()


def test_without_a_collision_the_route_is_not_asked(checker):
    far = np.array([-0.15, 0.32, 0.06])  # a straight run from here to a goal beside the wall is free
    calls = []
    run = GoalTimeMPC(_mppi([UntilGoalCost([CollisionCost(checker, load_robot("sphere:0.015"))]), GoalAtTime()]), SCHEDULE, VMAX, "goal_raw",
                      search=_mppi([GoalAtTime()]), route=lambda a, b: calls.append(1))  # fmt: skip
    run.route_plan(far, 1.0)
    assert run.route_outcome == "searched plan free" and not calls
