"""GoalPoseCost computes only its link's chain: same poses as the all-links reference FK."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.planners import GoalPoseCost
from splatplan.planners.costs import Rollout
from splatplan.robots import load_robot
from splatplan.robots.kinematics import chain_pose, link_chain


@pytest.mark.parametrize("name", ["panda", "go2"])
def test_chain_pose_matches_the_reference_fk(name):
    robot = load_robot(name)
    q = robot.q_default + np.random.default_rng(0).normal(0, 0.5, (3, 4, robot.dof))
    ref = robot.link_poses(q)  # (3, 4, L, 4, 4)
    for l in range(len(robot.link_names)):
        np.testing.assert_allclose(chain_pose(link_chain(robot.kin, l), q), ref[..., l, :, :], atol=1e-12)


def test_goal_cost_uses_the_chain():
    robot = load_robot("panda")
    q = robot.q_default + np.random.default_rng(1).normal(0, 0.3, (5, 6, robot.dof))
    cost = GoalPoseCost(robot, position=(0.4, 0.1, 0.3), quat=(0, 1, 0, 0), link="panda_hand", terminal_factor=2.0)
    roll = Rollout(q, np.zeros_like(q), 0.05)
    t = robot.link_poses(q)[..., robot.link_names.index("panda_hand"), :, :]
    ang = np.arccos(np.clip(0.5 * (np.einsum("...ij,ij->...", t[..., :3, :3], np.diag([1.0, -1.0, -1.0])) - 1), -1, 1))
    per = np.linalg.norm(t[..., :3, 3] - [0.4, 0.1, 0.3], axis=-1) + 0.2 * ang
    np.testing.assert_allclose(cost(roll), per.sum(1) + 2.0 * per[:, -1], rtol=1e-10)


@pytest.mark.parametrize("device", ["cpu"] + (["cuda:0"] if __import__("splatplan._warp", fromlist=["wp"]).wp().is_cuda_available() else []))
def test_goal_cost_on_a_device_matches_the_host_chain(device):
    """device=...: the link pose from the Warp FK kernel (float32) gives the host float64 cost."""
    robot = load_robot("panda")
    q = robot.q_default + np.random.default_rng(2).normal(0, 0.4, (8, 5, robot.dof))
    roll = Rollout(q, np.zeros_like(q), 0.05)
    kw = dict(position=(0.4, 0.1, 0.3), quat=(0, 1, 0, 0), link="panda_hand_tcp", terminal_factor=3.0)
    host = GoalPoseCost(robot, **kw)(roll)
    dev = GoalPoseCost(robot, device=device, **kw)(Rollout(q, np.zeros_like(q), 0.05))
    np.testing.assert_allclose(dev, host, rtol=1e-4, atol=1e-4)  # float32 FK; angles near 0 lose most


def test_fk_device_is_the_checkers():
    """The arm task's goal cost runs the Warp FK kernel wherever the checker runs (CPU included)."""
    from types import SimpleNamespace

    from splatplan.planners.costs import fk_device

    assert fk_device(SimpleNamespace(device="cpu")) == "cpu"
    assert fk_device(SimpleNamespace(device="cuda:0")) == "cuda:0"
