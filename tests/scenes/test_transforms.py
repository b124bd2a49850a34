"""Transform properties: covariances follow Sigma' = R Sigma R^T, scaling by f scales them by f^2."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from splatplan.errors import SplatplanError
from splatplan.scenes import quat_to_rotmat, transforms

from .scene_encoders import random_splats

SCENE = random_splats(64, k_sh=3, seed=0)
SCENE_2D = random_splats(64, is_2d=True, seed=1)

quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).map(np.array).filter(lambda q: np.linalg.norm(q) > 0.1)
vec3 = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(np.array)


@settings(max_examples=30, deadline=None)
@given(q=quats, t=vec3, as_matrix=st.booleans(), disks=st.booleans())
def test_rigid_transform_covariance(q, t, as_matrix, disks):
    s = SCENE_2D if disks else SCENE
    r = quat_to_rotmat(q)
    out = transforms.apply_rigid(s, r if as_matrix else q, t)
    np.testing.assert_allclose(out.means, s.means.astype(np.float64) @ r.T + t, atol=1e-5)
    np.testing.assert_allclose(out.covariances(), r @ s.covariances() @ r.T, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(out.quats, axis=1), 1.0, atol=1e-6)
    np.testing.assert_array_equal(out.scales, s.scales)
    assert out.is_2d == disks
    assert out.sh_rest is s.sh_rest or np.array_equal(out.sh_rest, s.sh_rest)  # SH not rotated


@settings(max_examples=20, deadline=None)
@given(q=quats, t=vec3)
def test_pairwise_distances_preserved(q, t):
    out = transforms.apply_rigid(SCENE, q, t)
    d0 = np.linalg.norm(SCENE.means[:, None] - SCENE.means[None], axis=-1)
    d1 = np.linalg.norm(out.means[:, None] - out.means[None], axis=-1)
    np.testing.assert_allclose(d1, d0, atol=1e-4)


def test_rotate_quaternion_matches_scipy():
    q = np.array([0.9, 0.1, -0.3, 0.2])
    q /= np.linalg.norm(q)
    out = transforms.rotate(SCENE, q)
    ref = Rotation.from_quat(np.r_[q[1:], q[0]]).apply(SCENE.means)
    np.testing.assert_allclose(out.means, ref, atol=1e-5)


def test_translate_and_scale():
    out = transforms.translate(SCENE, [1.0, -2.0, 3.0])
    np.testing.assert_allclose(out.means, SCENE.means + [1.0, -2.0, 3.0], atol=1e-6)
    np.testing.assert_array_equal(out.quats, SCENE.quats)
    big = transforms.scale(SCENE, 2.5)
    np.testing.assert_allclose(big.means, 2.5 * SCENE.means, rtol=1e-6)
    np.testing.assert_allclose(big.covariances(), 6.25 * SCENE.covariances(), rtol=1e-5, atol=1e-12)
    with pytest.raises(SplatplanError):
        transforms.scale(SCENE, -1.0)


def test_y_down_to_z_up_axis_map():
    s = random_splats(3, seed=2)
    s.means[:] = np.eye(3)  # +x, +y (down), +z (forward)
    out = transforms.y_down_to_z_up(s)
    np.testing.assert_allclose(out.means, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-7)
    assert np.isclose(np.linalg.det(transforms.Y_DOWN_TO_Z_UP), 1.0)


def test_normalize_to_unit():
    out, t = transforms.normalize_to_unit(SCENE)
    lo, hi = out.bounds()
    assert np.isclose(np.max(hi - lo), 1.0, atol=1e-6)
    np.testing.assert_allclose(0.5 * (lo + hi), 0.0, atol=1e-6)
    homog = np.c_[SCENE.means.astype(np.float64), np.ones(len(SCENE))] @ t.T
    np.testing.assert_allclose(homog[:, :3], out.means, atol=1e-6)
    np.testing.assert_allclose(out.scales, SCENE.scales * t[0, 0], rtol=1e-6)


def test_bad_rotations():
    with pytest.raises(SplatplanError, match="non-zero"):
        transforms.rotate(SCENE, np.zeros(4))
    with pytest.raises(SplatplanError, match="determinant"):
        transforms.rotate(SCENE, np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(SplatplanError, match="shape"):
        transforms.rotate(SCENE, np.eye(2))
