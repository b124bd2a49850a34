"""The Go2 in narrow free space: drives that stop at their target, route tracking (RouteTracker),
`mpc`'s route by default when the straight line is blocked, and the goal rule of benchmarks/real_go2.py."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners.drive import RouteTracker


def test_route_tracker_leads_by_the_lookahead_and_never_goes_back():
    route = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, np.pi / 2]])
    tr = RouteTracker(route, lookahead=0.3)
    tgt, yaw = tr.target(np.array([0.0, 0.05]))
    np.testing.assert_allclose(tgt, [0.3, 0.0], atol=0.021)
    assert yaw == pytest.approx(0.0, abs=1e-9)
    tr.target(np.array([0.5, 0.0]))  # the progress advances at most 2 lookaheads per call
    tgt, yaw = tr.target(np.array([0.9, 0.0]))  # round the corner: the target is on the second leg, the yaw turning
    assert tgt[0] == pytest.approx(1.0) and 0.1 < tgt[1] < 0.3 and 0.0 < yaw < np.pi / 2
    tgt2, _ = tr.target(np.array([0.2, 0.0]))  # back near the start: the progress stays
    assert tgt2[1] >= tgt[1] - 1e-9
    tr.target(np.array([1.0, 0.5]))
    tgt, yaw = tr.target(np.array([1.0, 0.95]))  # the end: the goal and the route's last heading
    np.testing.assert_allclose(tgt, [1.0, 1.0])
    assert yaw == pytest.approx(np.pi / 2)


def test_route_tracker_follows_a_route_that_doubles_back_in_order():
    route = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.02]])  # out and back, 2 cm apart: (P, 2), yaw along it
    tr = RouteTracker(route, lookahead=0.2)
    tgt, yaw = tr.target(np.array([0.1, 0.01]))
    assert tgt[0] > 0.1 and yaw == pytest.approx(0.0, abs=1e-9)  # outward first, not the return leg
    for x in np.linspace(0.2, 1.0, 9):
        tr.target(np.array([x, 0.01]))
    tgt, yaw = tr.target(np.array([0.9, 0.015]))
    assert tgt[0] < 0.9 and abs(abs(yaw) - np.pi) < 0.1  # now homeward
    with pytest.raises(SplatplanError):
        RouteTracker(np.zeros((3,)), 0.3)


@pytest.fixture(scope="module")
def corridor():
    """A 2 m long corridor along x, 0.7 m wide between two walls of splats, and a wall across it at x = 1."""
    from splatplan.metric import CollisionChecker
    from splatplan.scenes import Splats
    from splatplan.tasks.base import load_go2

    rng = np.random.default_rng(0)

    def wall(lo, hi, n):
        return rng.uniform(lo, hi, (n, 3))

    side = np.concatenate([wall([-1.0, 0.35, 0.0], [3.0, 0.37, 0.6], 3000), wall([-1.0, -0.37, 0.0], [3.0, -0.35, 0.6], 3000)])
    across = wall([0.99, -0.35, 0.0], [1.01, 0.35, 0.6], 1500)
    s = np.concatenate([side, across])
    splats = Splats(s, np.tile([1.0, 0, 0, 0], (len(s), 1)), np.full((len(s), 3), 0.01), np.full(len(s), 0.9), np.full((len(s), 3), 0.5))
    open_ = splats.subset(np.arange(len(s)) < len(side))
    return load_go2(), CollisionChecker(open_, n_sigma=0.75), CollisionChecker(splats, n_sigma=0.75)


def test_straight_line_blocked(corridor):
    from splatplan.cli.mpc import straight_line_blocked

    robot, open_, closed = corridor
    start, goal = np.array([-0.5, 0.0, 0.0]), np.array([2.0, 0.0])
    assert not np.asarray(open_.collides_robot(robot, np.array([start, [2.0, 0.0, 0.0]]))).any()
    assert not straight_line_blocked(robot, open_, start, goal)  # along the corridor, facing it
    assert straight_line_blocked(robot, closed, start, goal)


def test_the_drive_to_the_goal_stops_there(corridor):
    """In a small room every drive that runs on at full speed meets a wall within the 4 s horizon;
    the drive along the bearing (and those that turn to it) stop at the goal and stay collision-free."""
    from splatplan.planners import MPPI, CollisionCost, PlanarBase
    from splatplan.planners.drive import DriveGoalCost, StructuredDrives
    from splatplan.tasks.base import BaseConfig

    robot, open_, _ = corridor
    cfg = BaseConfig()
    x = np.array([-0.5, 0.0, 0.0])
    goal = np.array([0.3, 0.0])
    vmax = np.asarray(robot.velocity_limits)
    cost = CollisionCost(open_, robot, weight=cfg.w_collision, hit_weight=cfg.w_hit, s2_cap=cfg.collision_s2_cap)
    goal_cost = DriveGoalCost(goal, w_goal=cfg.w_goal, terminal_factor=cfg.terminal_factor, min_factor=cfg.min_factor, w_heading=cfg.w_heading)
    drives = StructuredDrives(goal_cost, n_directions=cfg.n_directions, speed=cfg.primitive_speed, turn_rate=cfg.primitive_turn_rate)
    mppi = MPPI(PlanarBase(robot), None, replace(cfg.mppi, u_min=tuple(-vmax), u_max=tuple(vmax)), costs=[cost, goal_cost], sampler=drives)
    drives.bind(mppi.spline.basis, mppi.config.dt)
    ev = mppi.evaluate(x, mppi.clip(drives.primitives(x)))
    m = cfg.n_directions
    to_goal = np.r_[0, np.arange(m, 4 * m)]  # the bearing drive and every switching drive
    end = ev.states[to_goal, -1, :2]
    assert np.linalg.norm(end[0] - goal) < 0.05  # the B-spline fit rounds the stop a little
    assert ev.query is not None and not ev.in_collision()[0]
    assert np.abs(ev.states[0, :, 2]).max() < 0.05  # facing the goal all along: no turn when it stops


def test_real_go2_goal_rule_on_a_synthetic_map():
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import real_go2

    xs, ys = np.arange(0.05, 2.0, 0.1), np.arange(0.05, 1.0, 0.1)
    yaws = np.linspace(-np.pi, np.pi, real_go2.N_YAWS, endpoint=False)
    free = np.zeros((len(xs), len(ys), real_go2.N_YAWS), bool)
    free[2:18, 3:7, :6] = True  # a strip free at 6 headings
    free[8:11, 4:6, :] = True  # an open spot in it: the start
    free[0, 0, :] = True  # an island: never a goal
    start, goals, comp = real_go2.pick_start_and_goals(xs, ys, yaws, free, n_goals=3)
    assert 8 <= np.searchsorted(xs, start[0]) <= 11
    assert len(goals) == 3 and not comp[0, 0]
    assert np.all(np.linalg.norm(goals - start[:2], axis=1) >= 0.5)
    assert {round(goals[0][0], 2), round(goals[1][0], 2)} == {round(xs[2], 2), round(xs[17], 2)}  # the strip's two ends first


def test_safe_step_halves_or_holds_a_colliding_motion(corridor):
    from splatplan.planners.dynamics import PlanarBase
    from splatplan.tasks._common import densify, safe_step

    robot, _, closed = corridor  # the wall across the corridor at x = 1: the base touches it from x ~ 0.57 on
    dyn = PlanarBase(robot)
    free = ~np.asarray(closed.collides_robot(robot, np.array([[0.42, 0, 0], [0.52, 0, 0], [0.55, 0, 0], [0.6, 0, 0], [0.62, 0, 0]]))).any(-1)
    assert free.tolist() == [True, True, True, False, False]
    x = np.array([0.42, 0.0, 0.0])
    u, x1 = safe_step(robot, closed, dyn, x, np.array([0.4, 0.0, 0.0]), 0.2)  # 8 cm: free
    np.testing.assert_allclose(u, [0.4, 0, 0])
    u, x1 = safe_step(robot, closed, dyn, x, np.array([1.0, 0.0, 0.0]), 0.2)  # 20 cm: into the wall; 10 cm: free
    np.testing.assert_allclose(u, [0.5, 0, 0])
    assert not np.asarray(closed.collides_robot(robot, densify(robot, np.stack([x, x1])))).any()
    u, x1 = safe_step(robot, closed, dyn, np.array([0.55, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), 0.2)  # even 5 cm collides: hold
    assert x1 is None and not u.any()


def test_heading_ref_replaces_the_face_the_goal_term_and_steers_the_drives(corridor):
    """Route tracking: the goal term's heading part is w_heading sum_t (1 - cos(yaw_t - heading_ref)),
    also next to the goal (no cutoff), and every structured drive turns towards heading_ref; a
    drive with zero velocity keeps its heading."""
    from splatplan.planners import MPPI, MPPIConfig, PlanarBase
    from splatplan.planners.drive import DriveGoalCost, StructuredDrives

    robot, _, _ = corridor
    goal = np.array([1.0, 0.0])
    rng = np.random.default_rng(1)
    states = np.concatenate([rng.uniform(-1, 2, (5, 7, 2)), rng.uniform(-np.pi, np.pi, (5, 7, 1))], axis=-1)  # (K, T, 3)
    states[0, :, :2] = goal + 0.01  # at the goal: the bearing term would be cut off there
    cost = DriveGoalCost(goal, w_heading=0.7)
    plain, dist = cost.goal_cost(states)
    cost.heading_ref = 0.4
    ref, _ = cost.goal_cost(states)
    gd = dist.sum(axis=1) + 5.0 * dist[:, -1] + 5.0 * dist.min(axis=1)
    np.testing.assert_allclose(ref, gd + 0.7 * (1.0 - np.cos(states[..., 2] - 0.4)).sum(axis=1), rtol=1e-12)
    assert not np.allclose(ref, plain)

    vmax = tuple(np.asarray(robot.velocity_limits))
    drives = StructuredDrives(cost, n_directions=8)
    mppi = MPPI(PlanarBase(robot), None, MPPIConfig(n_samples=64, horizon=20, n_knots=6, dt=0.2, n_iters=1, clamped_spline=False, u_min=tuple(-v for v in vmax), u_max=vmax),
                costs=[cost], sampler=drives)  # fmt: skip
    drives.bind(mppi.spline.basis, mppi.config.dt)
    x = np.array([0.0, 0.0, -1.0])
    ev = mppi.evaluate(x, mppi.clip(drives.primitives(x)))
    err = np.abs(np.angle(np.exp(1j * (ev.states[:, -1, 2] - 0.4))))  # (P,) from 1.4 rad off: every drive turns to heading_ref
    assert err.max() < 0.35, err.max()  # (the ridge fit of the knots rounds the turn)
    assert np.ptp(ev.states[:, -1, 2]) < 0.05  # whatever its direction of travel
    cost.heading_ref = None
    ev = mppi.evaluate(x, mppi.clip(drives.primitives(x)))
    assert np.ptp(ev.states[:, -1, 2]) > 1.0  # without it: each towards its own direction of travel
    still = drives._drive_knots(x, np.zeros((1, 20, 2)))  # a stopped drive: no turn at all
    np.testing.assert_allclose(still, 0.0, atol=1e-12)


def test_run_base_holds_a_colliding_step_and_restarts_mppi(corridor, monkeypatch):
    """With the collision cost weighted 0 the nominal drives into the wall across the corridor:
    safe_step holds the base before it (positive clearance), counts the held steps and restarts
    MPPI from standing still through its public reset(); without safe_step it drives through."""
    from splatplan.planners import MPPI
    from splatplan.tasks._common import TaskScene
    from splatplan.tasks.base import BaseConfig, run_base

    robot, _, closed = corridor
    ts = TaskScene("corridor", closed.scene, closed, None)
    resets = []
    orig = MPPI.reset

    def reset(self, *args, **kwargs):
        resets.append((args, kwargs))
        orig(self, *args, **kwargs)

    monkeypatch.setattr(MPPI, "reset", reset)
    cfg = BaseConfig(max_steps=15, w_collision=0.0, w_hit=0.0)
    r = run_base(robot, ts, (2.0, 0.0), start=(0.3, 0.0, 0.0), config=cfg, device="cpu")
    assert r.extra["n_held_steps"] > 0 and len(resets) == r.extra["n_held_steps"] and r.min_clearance_m > 0
    assert r.trajectory[-1, 0] < 0.6  # stopped before the wall at x = 1 (the body reaches ~0.43 m ahead)
    r = run_base(robot, ts, (2.0, 0.0), start=(0.3, 0.0, 0.0), config=replace(cfg, safe_step=False), device="cpu")
    assert r.extra["n_held_steps"] == 0 and r.min_clearance_m < 0
