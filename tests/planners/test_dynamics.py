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
    with pytest.raises(SplatplanError):
        JointIntegrator(fk, q_min=[1.0], q_max=[0.0], semi_axes=[[0.1, 0.1, 0.1]])
    with pytest.raises(SplatplanError):
        dyn.rollout(np.zeros(3), u, 0.1)
