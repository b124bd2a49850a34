"""IK errors a user can act on: an unreachable pose gives the nearest reachable pose found (pasteable
as ``--goal-pose``); a pose whose every solution collides names the links and the splats they hit."""

from __future__ import annotations

import re

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes import Splats



def _blob(centre, half: float, n: int = 20000, seed: int = 0) -> Splats:
    """An opaque cube of splats of half side ``half`` around ``centre``."""
    m = np.random.default_rng(seed).uniform(-half, half, (n, 3)) + np.asarray(centre)
    return Splats(m, np.tile([1.0, 0, 0, 0], (n, 1)), np.full((n, 3), 0.005), np.full(n, 0.9), np.full((n, 3), 0.5))


def _pose_in(msg: str) -> np.ndarray:
    m = re.search(r"--goal-pose ((?:-?\d+\.\d+,){6}-?\d+\.\d+)", msg)
    assert m, msg
    return np.array([float(v) for v in m.group(1).split(",")])


@pytest.fixture(scope="module")
def panda():
    from splatplan.robots import load_robot

    return load_robot("panda")


def test_unreachable_pose_gives_the_nearest_reachable_one(panda):
    from splatplan.metric import CollisionChecker
    from splatplan.robots.ik import collision_free_ik, solve_ik

    checker = CollisionChecker(_blob([5.0, 5.0, 5.0], 0.1, n=100), n_sigma=1.0, device="cpu")  # nothing near the arm
    with pytest.raises(SplatplanError) as e:
        collision_free_ik(panda, checker, [2.0, 0.0, 0.5], [0.0, 1.0, 0.0, 0.0], link="panda_hand_tcp", seed=0)
    msg = str(e.value)
    assert "unreachable" in msg and "nearest reachable pose" in msg
    pose = _pose_in(msg)
    assert np.linalg.norm(pose[:3]) < 1.2 and np.linalg.norm(pose[3:]) == pytest.approx(1.0, abs=1e-3)
    # the suggested pose is one the arm reaches (to the 0.1 mm of its 4 decimals)
    _, pe, re_ = solve_ik(panda, pose[:3], pose[3:], link="panda_hand_tcp", seed=1)
    assert pe[0] < 1e-3 and re_[0] < np.radians(0.5)
    q = collision_free_ik(panda, checker, pose[:3], pose[3:], link="panda_hand_tcp", seed=1)
    assert q.shape == (7,)


def test_mpc_reachability_check_gives_the_nearest_pose_too(panda):
    from splatplan.robots.ik import check_reachable, down_quat

    for goal in ([1.5, 0.0, 0.3], [0.0, 0.0, 1.15]):  # beyond the reach sphere; inside it but unreachable
        with pytest.raises(SplatplanError, match="unreachable goal pose") as e:
            check_reachable(panda, goal, down_quat(), "panda_hand_tcp", n_seeds=4)
        assert _pose_in(str(e.value)).shape == (7,)


def test_link_pose_round_trips_through_ik(panda):
    from splatplan.robots.ik import format_pose, link_pose

    q = np.asarray(panda.q_default, np.float64)
    p = link_pose(panda, q, "panda_hand_tcp")
    t = panda.link_poses(q[None])[0, list(panda.link_names).index("panda_hand_tcp")]
    np.testing.assert_allclose(p[:3], t[:3, 3], atol=1e-12)
    assert p[3] >= 0 and np.linalg.norm(p[3:]) == pytest.approx(1.0)
    assert len(format_pose(p).split(",")) == 7


def test_all_solutions_in_collision_name_links_and_where(panda):
    from splatplan.metric import CollisionChecker
    from splatplan.robots.ik import collision_free_ik

    goal = np.array([0.5, 0.0, 0.3])
    checker = CollisionChecker(_blob(goal, 0.08), n_sigma=1.0, device="cpu")  # the goal lies inside an opaque cube
    with pytest.raises(SplatplanError) as e:
        collision_free_ik(panda, checker, goal, [0.0, 1.0, 0.0, 0.0], link="panda_hand_tcp", near=np.asarray(panda.q_default), seed=0)
    msg = str(e.value)
    assert "in collision" in msg and "at the one nearest the start" in msg
    hits = re.findall(r"(panda_\w+) hits (\d+) splat\(s\) around \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\)", msg)
    assert hits, msg
    for _, n, *xyz in hits:
        assert int(n) > 0 and np.all(np.abs(np.array(xyz, float) - goal) <= 0.08 + 1e-3)  # the centroid lies in the cube
    assert "panda_hand" in msg or "finger" in msg  # the links at the goal
