"""Arm and base MPPI tasks: tiny runs on small built-in scenes, IK, reachability, start checks."""

from __future__ import annotations

import re

import numpy as np
import pytest

from splatplan.errors import SplatplanError


@pytest.fixture(scope="module")
def tabletop_small():
    from splatplan.tasks._common import load_task_scene

    return load_task_scene("tabletop", n_splats=20_000)


def test_ik_reaches_a_pose():
    from splatplan.robots import load_robot
    from splatplan.robots.ik import solve_ik
    from splatplan.robots.ik import down_quat

    robot = load_robot("panda")
    q, pe, re = solve_ik(robot, [0.5, 0.1, 0.3], down_quat(0.3), link="panda_hand_tcp", n_seeds=8, n_iters=60)
    assert pe[0] < 1e-3 and re[0] < 1e-2
    t = robot.link_poses(q[0])[robot.link_names.index("panda_hand_tcp")]
    np.testing.assert_allclose(t[:3, 3], [0.5, 0.1, 0.3], atol=1e-3)


def test_unreachable_goal_is_reported_before_running():
    from splatplan.robots import load_robot
    from splatplan.robots.ik import check_reachable, down_quat

    robot = load_robot("panda")
    with pytest.raises(SplatplanError, match="unreachable goal pose"):
        check_reachable(robot, [1.5, 0.0, 0.3], down_quat(), "panda_hand_tcp")
    with pytest.raises(SplatplanError, match="unreachable goal pose"):  # inside the reach sphere but not reachable
        check_reachable(robot, [0.0, 0.0, 1.15], down_quat(), "panda_hand_tcp", n_seeds=4)


def test_tiny_arm_run_reduces_goal_error(tabletop_small):
    from dataclasses import replace

    from splatplan.robots.ik import down_quat
    from splatplan.tasks.arm import ArmConfig, run_arm

    goal = np.array([0.45, 0.0, 0.35])
    cfg = ArmConfig(max_steps=12, collision_stride=4)
    cfg = replace(cfg, mppi=replace(cfg.mppi, n_samples=16, horizon=8))
    r = run_arm("panda", tabletop_small, goal, down_quat(0.0), config=cfg, check_goal=False)
    from splatplan.robots import load_robot

    robot = load_robot("panda")
    e0 = np.linalg.norm(robot.link_poses(robot.q_default)[robot.link_names.index("panda_hand_tcp"), :3, 3] - goal)
    assert r.final_position_error_m < 0.7 * e0
    assert r.clearance_source == "analytic" and np.isfinite(r.min_clearance_m)
    assert r.trajectory.shape[1] == 7 and r.collision_cost
    d = r.to_json()
    assert set(d) >= {"success", "trajectory", "min_clearance_m", "final_position_error_m", "time_s", "steps_per_s"}


def test_start_in_collision_names_links(tabletop_small):
    from splatplan.robots import load_robot
    from splatplan.tasks._common import check_start

    robot = load_robot("panda")
    q = robot.q_default.copy()
    q[1] = 1.7  # shoulder forward: the arm lies on the table
    q[3] = -0.3
    with pytest.raises(SplatplanError, match=r"in collision.*panda_\w+ \(\d+ splats\)") as err:
        check_start(robot, tabletop_small.checker, q)
    named = re.findall(r"(panda_\w+) \(\d+ splats\)", str(err.value))
    assert named and len(named) == len(set(named))  # each link once


def test_tiny_base_run_moves_toward_the_goal():
    from dataclasses import replace

    from splatplan.tasks.base import BaseConfig, load_go2, run_base

    cfg = BaseConfig(max_steps=10)
    cfg = replace(cfg, mppi=replace(cfg.mppi, n_samples=16, horizon=10))
    start = np.array([-2.3, -0.6, 0.0])
    goal = np.array([-1.0, 2.0])
    r = run_base(load_go2(), "apartment", goal, start=start, config=cfg)
    assert r.final_position_error_m < np.linalg.norm(start[:2] - goal) - 0.3
    assert r.min_clearance_m > 0 and r.clearance_source == "analytic"
    with pytest.raises(SplatplanError, match="collides there at every heading"):
        run_base(load_go2(), "apartment", (-3.45, 0.4), start=start, config=cfg)  # inside the sofa


def test_densify_bounds_motion():
    from splatplan.robots import load_robot
    from splatplan.tasks._common import densify

    robot = load_robot("panda")
    a, b = robot.q_default, robot.q_default + 0.3
    q = densify(robot, np.stack([a, b]), step_m=0.01)
    steps = np.sum(robot.motion_bound * np.abs(np.diff(q, axis=0)), axis=1)
    assert steps.max() <= 0.01 + 1e-12 and np.allclose(q[-1], b)


def test_bad_prune_margin_exits_2_with_one_line(tmp_path, capsys):
    """`mpc --robot panda --arm-mppi-prune-margin` with an impossible value: one named stderr line, exit 2, no folder."""
    from splatplan.cli import main

    for value in ("-1", "0", "nan"):
        out = tmp_path / f"run{value}"
        rc = main(["mpc", "--robot", "panda", "--scene", "tabletop", "--goal-pose", "0.5,0,0.3,0,1,0,0", "--arm-mppi-prune-margin", value, "--out", str(out)])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "prune_margin" in err[0] and "Traceback" not in err[0], (value, err)
        assert not out.exists()


def test_run_clearance_equals_the_full_evaluation(tabletop_small):
    """A run's every-link and moving-link minimum clearances (one evaluation that solves only the
    pairs that can hold a minimum) are those of the full per-ellipsoid evaluation, exact geometry
    and the metric's estimate alike, on a free and a penetrating trajectory."""
    from dataclasses import replace

    from splatplan.robots import load_robot
    from splatplan.planners.clearance import s2_to_metres
    from splatplan.tasks._common import densify, moving_ellipsoids, run_clearance

    robot = load_robot("panda")
    mov = moving_ellipsoids(robot)
    assert 0 < mov.sum() < robot.n_ellipsoids  # (the fixed base link)
    free = np.stack([robot.q_default, robot.q_default + np.array([0.4, 0.5, 0.0, -0.3, 0.0, 0.3, 0.0])])
    down = np.stack([robot.q_default, [0.75, 1.51, -0.35, -0.21, 0.0, 1.59, 0.7]])  # ends 1 cm into the geometry
    for ts in (tabletop_small, replace(tabletop_small, analytic=None)):
        for states in (free, down):
            q = densify(robot, states)
            if ts.analytic is not None:  # the full per-ellipsoid evaluation (S', E)
                cc, qq, ax = robot.ellipsoids(q)
                full, s = ts.analytic.ellipsoid_clearance(cc, qq, ax), "analytic"
            else:
                full, s = s2_to_metres(ts.checker.query_robot(robot, q).min_s2, robot.semi_axes), "metric"
            lo, mo, src = run_clearance(robot, ts, states)
            assert src == s and lo == float(full.min()) and mo == float(full[:, mov].min()) and mo >= lo
    assert run_clearance(robot, tabletop_small, down)[0] < 0 < run_clearance(robot, tabletop_small, free)[0]  # (both cases met)
