"""Dynamics models: rollouts vs hand integration, link poses, joint limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners.dynamics import Dynamics, HolonomicPoint, JointIntegrator, PlanarBase, yaw_to_quat
from splatplan.scenes.splats import quat_to_rotmat


def test_holonomic_point_rollout():
    dyn = HolonomicPoint(semi_axes=(0.02, 0.02, 0.02))
    assert isinstance(dyn, Dynamics)
    u = np.random.default_rng(0).normal(size=(4, 10, 3))
    x0 = np.array([0.1, -0.2, 0.06])
    s = dyn.rollout(x0, u, 0.05)
    assert s.shape == (4, 10, 3)
    np.testing.assert_allclose(s[:, 0], x0 + 0.05 * u[:, 0])
    np.testing.assert_allclose(s[:, -1], x0 + 0.05 * u.sum(axis=1))
    c, q, a = dyn.link_poses(s)
    assert c.shape == (4, 10, 1, 3) and q is None and a.shape == (1, 3)


def test_planar_base_matches_hand_integration():
    dyn = PlanarBase(height=0.06)
    assert isinstance(dyn, Dynamics)
    dt = 0.1
    u = np.array([[[0.2, 0.0, 0.5], [0.1, 0.05, -1.0], [0.0, 0.3, 0.2]]])  # (1, 3, 3) body frame
    x = [0.0, 0.0, math.pi / 4]
    ref = []
    for vx, vy, wz in u[0]:  # hand-integrated forward Euler, heading at the start of the step
        c, s = math.cos(x[2]), math.sin(x[2])
        x = [x[0] + (c * vx - s * vy) * dt, x[1] + (s * vx + c * vy) * dt, x[2] + wz * dt]
        ref.append(x)
    out = dyn.rollout(np.array([0.0, 0.0, math.pi / 4]), u, dt)
    np.testing.assert_allclose(out[0], np.array(ref), atol=1e-12)
    # first step by hand: heading 45 deg, forward 0.2 * 0.1
    np.testing.assert_allclose(out[0, 0, :2], [0.02 / math.sqrt(2), 0.02 / math.sqrt(2)], atol=1e-12)


def test_planar_base_link_poses_rotate_with_yaw():
    dyn = PlanarBase(height=0.05, offsets=[[0.02, 0.0, 0.0], [-0.02, 0.01, 0.01]], semi_axes=[[0.02, 0.01, 0.01], [0.01, 0.01, 0.01]])
    states = np.array([[[0.1, 0.2, math.pi / 2]]])  # (1, 1, 3)
    c, q, a = dyn.link_poses(states)
    assert c.shape == (1, 1, 2, 3) and q.shape == (1, 1, 2, 4) and a.shape == (2, 3)
    np.testing.assert_allclose(c[0, 0, 0], [0.1, 0.22, 0.05], atol=1e-12)  # body x -> world y
    np.testing.assert_allclose(c[0, 0, 1], [0.09, 0.18, 0.06], atol=1e-12)
    r = quat_to_rotmat(q[0, 0, 0])
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(yaw_to_quat(np.array(0.0)), [1, 0, 0, 0])


def test_joint_integrator_limits_and_fk():
    def fk(q):  # planar 2-link arm, unit links, joint 1 at the origin; link centres mid-link
        a1 = q[..., 0]
        a2 = q[..., 0] + q[..., 1]
        p1 = np.stack([0.5 * np.cos(a1), 0.5 * np.sin(a1), 0 * a1], -1)
        p2 = np.stack([np.cos(a1) + 0.5 * np.cos(a2), np.sin(a1) + 0.5 * np.sin(a2), 0 * a1], -1)
        return np.stack([p1, p2], axis=-2), None

    with pytest.warns(DeprecationWarning, match="JointIntegrator\\(robot\\)"):  # the FK-callable form: deprecated in 0.3.0
        dyn = JointIntegrator(fk, q_min=[-1.0, -0.5], q_max=[1.0, 0.5], semi_axes=[[0.5, 0.05, 0.05]] * 2)
    assert isinstance(dyn, Dynamics) and dyn.state_dim == 2 and dyn.control_dim == 2
    u = np.ones((2, 20, 2))
    u[1] *= -1
    s = dyn.rollout(np.zeros(2), u, 0.1)
    np.testing.assert_allclose(s[0, -1], [1.0, 0.5])
    np.testing.assert_allclose(s[1, -1], [-1.0, -0.5])
    np.testing.assert_allclose(s[0, 2], [0.3, 0.3])
    c, q, a = dyn.link_poses(s)
    assert c.shape == (2, 20, 2, 3) and a.shape == (2, 3)
    with pytest.raises(SplatplanError), pytest.warns(DeprecationWarning):
        JointIntegrator(fk, q_min=[1.0], q_max=[0.0], semi_axes=[[0.1, 0.1, 0.1]])
    with pytest.raises(SplatplanError):
        dyn.rollout(np.zeros(3), u, 0.1)


def test_joint_integrator_limits_from_a_robot(tmp_path):
    """The limits and link poses of the test above, from a Robot (the form that stays): a 2-joint
    planar arm loaded from a URDF, its limits overridden as ``q_min`` / ``q_max``."""
    from splatplan.robots import load_robot

    (tmp_path / "arm.urdf").write_text(
        """<robot name="arm">
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="1 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>"""
    )
    (tmp_path / "arm.ellipsoids.yaml").write_text(
        "ellipsoids:\n- {link: l1, center: [0.5, 0, 0], semi_axes: [0.5, 0.05, 0.05]}\n- {link: l2, center: [0.5, 0, 0], semi_axes: [0.5, 0.05, 0.05]}\n"
    )
    arm = load_robot(tmp_path / "arm.urdf")
    assert arm.base == "fixed" and arm.dof == 2
    dyn = JointIntegrator(arm, q_min=[-1.0, -0.5], q_max=[1.0, 0.5], velocity_limits=10.0)
    u = np.ones((2, 20, 2))
    u[1] *= -1
    s = dyn.rollout(np.zeros(2), u, 0.1)
    np.testing.assert_allclose(s[0, -1], [1.0, 0.5])
    np.testing.assert_allclose(s[1, -1], [-1.0, -0.5])
    c, _, a = dyn.link_poses(s)
    assert c.shape == (2, 20, 2, 3) and a.shape == (2, 3)
    a1, a2 = s[0, 2, 0], s[0, 2].sum()
    np.testing.assert_allclose(c[0, 2, 1], [np.cos(a1) + 0.5 * np.cos(a2), np.sin(a1) + 0.5 * np.sin(a2), 0.0], atol=1e-12)
    np.testing.assert_allclose(dyn.speed_bound(), [10.0, 10.0])
    with pytest.raises(SplatplanError, match="semi_axes"):
        JointIntegrator(arm, semi_axes=[[0.1, 0.1, 0.1]] * 2)
    with pytest.raises(SplatplanError, match="Robot"):
        JointIntegrator("not a robot")


def test_models_check_the_kind_of_robot():
    from splatplan.robots import load_robot

    sphere, go2 = load_robot("sphere:0.02"), load_robot("go2")
    assert HolonomicPoint(sphere).robot is sphere and HolonomicPoint(robot=sphere).robot is sphere
    with pytest.raises(SplatplanError, match="point robot"):
        HolonomicPoint(go2)
    with pytest.raises(SplatplanError, match="planar-base"):
        PlanarBase(sphere)
    with pytest.raises(SplatplanError, match="planar-base"):
        PlanarBase(load_robot("ellipsoid:0.03,0.02,0.01"))  # a point (x, y, z), not a planar base
    assert PlanarBase(load_robot("ellipsoid:0.03,0.02,0.01", base="planar")).robot.base == "planar"
    with pytest.warns(DeprecationWarning, match="semi_axes="):
        dyn = HolonomicPoint((0.02, 0.03, 0.04))  # the old positional semi-axes, deprecated (0.3.0)
    assert dyn.robot is None and dyn.link_poses(np.zeros((1, 3)))[2].tolist() == [[0.02, 0.03, 0.04]]
    with pytest.raises(SplatplanError, match="does not bound its speed"):
        HolonomicPoint(sphere).speed_bound()
