"""Static ellipsoids (fixed to the world) are queried once by CollisionCost: same costs as querying them all."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.planners import CollisionCost, JointIntegrator, MPPI, MPPIConfig, PlanarBase
from splatplan.planners.costs import Rollout
from splatplan.robots import load_robot
from splatplan.robots.kinematics import FIXED

from .scenes import make_checker, make_scene

#: a table top under the Panda's base (touching link0) and a block in front of the arm
BOXES = [((-0.3, -0.3, -0.02), (0.6, 0.3, 0.0)), ((0.25, -0.15, 0.45), (0.4, 0.15, 0.75))]


@pytest.fixture(scope="module")
def panda():
    # the coarse model: one ellipsoid on link0, which reaches down to the table top of BOXES (the
    # tight model's link0 ellipsoids are several and hug the base)
    return load_robot("panda", model="coarse")


def test_static_mask_of_the_default_tight_model():
    tight = load_robot("panda")
    names = [tight.link_names[l] for l in tight.ellipsoid_link[tight.static_ellipsoids]]
    assert set(names) == {"panda_link0"} and len(names) == int(np.sum(tight.ellipsoid_link == tight.link_names.index("panda_link0"))) > 1


@pytest.fixture(scope="module")
def checker():
    return make_checker(make_scene(BOXES, spacing=0.02))


def test_static_mask_from_the_kinematic_tree(panda):
    assert panda.static_ellipsoids.shape == (panda.n_ellipsoids,)
    names = [panda.link_names[l] for l in panda.ellipsoid_link[panda.static_ellipsoids]]
    assert names == ["panda_link0"]
    # a static link's pose never changes; every other ellipsoid moves for some configuration
    rng = np.random.default_rng(0)
    lo, hi = panda.joint_limits[:, 0], panda.joint_limits[:, 1]
    q = lo + rng.random((20, panda.dof)) * (hi - lo)
    c, r = panda.ellipsoid_frames(q)
    still = np.all(np.abs(c - c[:1]) < 1e-12, axis=(0, 2)) & np.all(np.abs(r - r[:1]) < 1e-12, axis=(0, 2, 3))
    np.testing.assert_array_equal(still, panda.static_ellipsoids)
    # definition: every joint from the root down to a static link is fixed
    kin = panda.kin
    for l in range(kin.n_links):
        path, k = [], l
        while k >= 0:
            path.append(k)
            k = int(kin.parent[k])
        assert panda.static_links[l] == all(int(kin.jtype[k]) == FIXED for k in path)


def test_planar_base_and_point_robots_have_no_static_ellipsoid():
    for name in ("go2", "sphere:0.02"):
        robot = load_robot(name)
        assert not robot.static_ellipsoids.any(), name
        assert not robot.static_links.any(), name


def test_mimic_joints_count_as_moving(panda):
    # the fingers follow finger_joint1 in the URDF; the loader bakes it (no dof), so they are
    # fixed to the hand, which moves: never static
    fingers = [i for i, n in enumerate(panda.link_names) if "finger" in n]
    assert fingers and not panda.static_links[fingers].any()


def _random_rollout(robot, rng, k=12, t_len=6, dt=0.05):
    dyn = JointIntegrator(robot)
    u = rng.normal(0, 1.5, (k, t_len, robot.dof))
    x0 = robot.q_default + rng.normal(0, 0.4, robot.dof)
    return Rollout(dyn.rollout(x0, u, dt), u, dt)


@pytest.mark.parametrize("stride", [1, 2])
def test_shortcut_gives_the_same_costs(panda, checker, stride):
    rng = np.random.default_rng(stride)
    fast = CollisionCost(checker, panda, weight=1.0, hit_weight=10.0, time_stride=stride)
    slow = CollisionCost(checker, panda, weight=1.0, hit_weight=10.0, time_stride=stride, static_shortcut=False)
    assert fast.static is not None and fast.static.sum() == 1 and slow.static is None
    saw_static_cost = False
    for _ in range(3):
        roll = _random_rollout(panda, rng)
        a = fast.query(Rollout(roll.states, roll.controls, roll.dt))
        b = slow.query(Rollout(roll.states, roll.controls, roll.dt))
        assert a.min_s2.shape == b.min_s2.shape == (12, len(fast.steps(6)), panda.n_ellipsoids)
        for f in ("n_colliding", "in_collision"):  # exact outputs: bit-identical
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
        # min_s2 is exact below the cap and only known to be >= cap above it (the two queries use
        # different grids, so they may visit different far splats)
        cap = fast.checker.config.s2_cap
        near = (a.min_s2 < cap) | (b.min_s2 < cap)
        np.testing.assert_array_equal(a.min_s2[near], b.min_s2[near])
        for f in ("cost", "softmin"):  # sums over splats: equal up to float32 summation order
            np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=1e-5, atol=1e-7, err_msg=f)
        ta, tb = fast.terms(Rollout(roll.states, roll.controls, roll.dt)), slow.terms(Rollout(roll.states, roll.controls, roll.dt))
        np.testing.assert_array_equal(ta["hit"], tb["hit"])
        np.testing.assert_allclose(ta["collision"], tb["collision"], rtol=1e-5)
        saw_static_cost |= bool(np.any(a.cost[..., fast.static] > 0))
    assert saw_static_cost  # the static link0 touches the table: its constant cost is really added


def test_static_result_is_cached_per_checker_config(panda, checker):
    cost = CollisionCost(checker, panda)
    rng = np.random.default_rng(5)
    cost.query(_random_rollout(panda, rng))
    first = cost._static_result()
    cost.query(_random_rollout(panda, rng))
    assert cost._static_result() is first
    cost.checker = cost.checker.with_config(s2_cap=3.0)
    other = cost._static_result()
    assert other is not first
    ref = cost.checker.query_robot(panda, panda.q_default[None])
    np.testing.assert_array_equal(other.min_s2, ref.min_s2[0, cost.static])


def test_mppi_step_with_the_shortcut_matches_the_full_query(panda, checker):
    cfg = MPPIConfig(n_samples=16, horizon=6, n_knots=4, dt=0.05, n_iters=1, noise_sigma=0.5, u_min=-1.0, u_max=1.0, seed=3)
    infos = []
    for shortcut in (True, False):
        mppi = MPPI(JointIntegrator(panda), checker, cfg)
        mppi.costs[0] = CollisionCost(checker, panda, static_shortcut=shortcut)
        infos.append(mppi.step(panda.q_default)[1])
    a, b = infos
    np.testing.assert_allclose(a.costs, b.costs, rtol=1e-5)
    np.testing.assert_array_equal(a.nominal_in_collision, b.nominal_in_collision)
    # the MPPI update weighs the samples by their costs (equal up to float32 summation order), so
    # the nominal trajectories agree to rounding, not bit for bit
    near = (a.nominal_min_s2 < 2.0) | (b.nominal_min_s2 < 2.0)
    np.testing.assert_allclose(a.nominal_min_s2[near], b.nominal_min_s2[near], rtol=1e-5)


def test_go2_cost_queries_every_ellipsoid(checker):
    go2 = load_robot("go2")
    cost = CollisionCost(checker, PlanarBase(go2))
    assert cost.static is None
