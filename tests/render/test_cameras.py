"""Cameras: look-at frames, mount offsets, cameras on robot links (stand-in robot and the Panda)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.render import Camera, MountedCamera, SplatRenderer, intrinsics_from_fov, look_at, mount_offset
from splatplan.render.cameras import invert_rigid

from .conftest import random_scene


class TranslationRobot:
    """Stand-in robot: one link 'body' at the translation q (..., 3), no rotation."""

    name = "stand-in"
    dof = 3
    link_names = ["world", "body"]

    def link_poses(self, q):
        q = np.asarray(q, dtype=np.float64)
        out = np.broadcast_to(np.eye(4), q.shape[:-1] + (2, 4, 4)).copy()
        out[..., 1, :3, 3] = q
        return out


def test_look_at_is_rigid_and_batched():
    eyes = np.random.default_rng(0).normal(size=(5, 3)) * 3
    v = look_at(eyes, np.zeros(3))
    assert v.shape == (5, 4, 4)
    r = v[:, :3, :3]
    np.testing.assert_allclose(r @ np.transpose(r, (0, 2, 1)), np.broadcast_to(np.eye(3), (5, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0)
    np.testing.assert_allclose(invert_rigid(v)[:, :3, 3], eyes, atol=1e-12)  # camera centres
    # the target lies on the optical axis (camera x = y = 0, z > 0)
    p = np.einsum("bij,j->bi", r, np.zeros(3)) + v[:, :3, 3]
    np.testing.assert_allclose(p[:, :2], 0.0, atol=1e-12)
    assert np.all(p[:, 2] > 0)
    with pytest.raises(SplatplanError, match="parallel"):
        look_at([0, 0, 2], [0, 0, 0], up=[0, 0, 1])
    with pytest.raises(SplatplanError, match="coincide"):
        look_at([1, 1, 1], [1, 1, 1])


def test_mount_offset_matches_look_at():
    """A camera on an identity link, looking along +x with z up, equals look_at from its position."""
    off = mount_offset((0.1, 0.2, 0.3), forward=(1, 0, 0), up=(0, 0, 1))
    np.testing.assert_allclose(invert_rigid(off), look_at([0.1, 0.2, 0.3], [1.1, 0.2, 0.3]), atol=1e-12)
    np.testing.assert_allclose(mount_offset(), np.eye(4))


def test_mounted_camera_on_a_translating_robot():
    robot = TranslationRobot()
    off = mount_offset((0.0, 0.0, 0.5), forward=(1, 0, 0), up=(0, 0, 1))
    cam = MountedCamera("body", off, intrinsics_from_fov(60, 24, 16), 24, 16)
    q = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 0.5], [3.0, 1.0, -1.0]])  # (K, dof)
    v = cam.viewmats(robot, q)
    assert v.shape == (3, 4, 4)
    for i in range(3):
        eye = q[i] + [0, 0, 0.5]
        np.testing.assert_allclose(v[i], look_at(eye, eye + [1, 0, 0]), atol=1e-12)
    assert cam.viewmats(robot, q.reshape(3, 1, 3)).shape == (3, 1, 4, 4)  # any batch shape
    scene = random_scene(60, seed=4)
    with SplatRenderer(scene, "cpu") as r:
        res = cam.render(r, robot, q)
        want = r.render(v, cam.Ks((3,)), 24, 16)
    np.testing.assert_array_equal(res.rgb, want.rgb)
    with pytest.raises(SplatplanError, match="no link 'hand'"):
        MountedCamera("hand").viewmats(robot, q)
    with pytest.raises(SplatplanError, match="rigid"):
        MountedCamera("body", np.diag([2.0, 1, 1, 1]))


def test_camera_type():
    cam = Camera.look_at([1, 2, 3], [0, 0, 0], fov_deg=50, width=32, height=24)
    v, k, w, h = Camera.stack([cam, cam])
    assert v.shape == (2, 4, 4) and k.shape == (2, 3, 3) and (w, h) == (32, 24)
    with pytest.raises(SplatplanError):
        Camera(np.eye(4), np.eye(3) * 0, 8, 8)
    with pytest.raises(SplatplanError, match="share one image size"):
        Camera.stack([cam, Camera.look_at([1, 2, 3], [0, 0, 0], width=8, height=8)])


def test_wrist_camera_on_the_panda():
    robots = pytest.importorskip("splatplan.robots")
    try:
        panda = robots.load_robot("panda")
    except Exception as exc:  # pragma: no cover - robot assets missing
        pytest.skip(f"panda not loadable: {exc}")
    cam = MountedCamera("panda_hand", mount_offset((0.0, 0.0, 0.05)), intrinsics_from_fov(70, 32, 32), 32, 32)
    rng = np.random.default_rng(0)
    lo, hi = panda.joint_limits[:, 0], panda.joint_limits[:, 1]
    q = np.vstack([panda.q_default, rng.uniform(lo, hi, (4, panda.dof))])  # (K, dof)
    v = cam.viewmats(panda, q)
    assert v.shape == (5, 4, 4)
    hand = panda.link_poses(q)[:, panda.link_names.index("panda_hand")]  # (K, 4, 4) world <- hand
    c2w = invert_rigid(v)
    # camera centre 5 cm along the hand's z axis, optical axis = hand z (the approach direction)
    np.testing.assert_allclose(c2w[:, :3, 3], hand[:, :3, 3] + 0.05 * hand[:, :3, 2], atol=1e-9)
    np.testing.assert_allclose(c2w[:, :3, 2], hand[:, :3, 2], atol=1e-9)
    # at home the hand points down: a splat on the floor below it is in view
    floor = hand[0, :3, 3] + 0.4 * hand[0, :3, 2]
    from splatplan.scenes.splats import Splats

    dot = Splats(floor[None], [[1, 0, 0, 0]], [[0.02, 0.02, 0.02]], [0.9], [[1, 1, 1]])
    with SplatRenderer(dot, "cpu") as r:
        res = cam.render(r, panda, q[:1])
    assert res.alpha[0, 15:17, 15:17].min() > 0.7  # centred in the image
    assert np.unravel_index(np.argmax(res.alpha[0]), (32, 32)) in ((15, 15), (15, 16), (16, 15), (16, 16))


def test_head_camera_on_the_go2_base():
    robots = pytest.importorskip("splatplan.robots")
    try:
        go2 = robots.load_robot("go2")
    except Exception as exc:  # pragma: no cover - robot assets missing
        pytest.skip(f"go2 not loadable: {exc}")
    head = MountedCamera("base", mount_offset((0.3, 0.0, 0.05), forward=(1, 0, 0), up=(0, 0, 1)))
    q = np.array([[0.0, 0.0, 0.0], [0.1, 0.2, np.pi / 2], [-0.4, 0.3, -2.0]])  # (K, 3) x, y, yaw
    c2w = invert_rigid(head.viewmats(go2, q))
    base = go2.link_poses(q)[:, go2.link_names.index("base")]
    for i, yaw in enumerate(q[:, 2]):
        fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        np.testing.assert_allclose(c2w[i, :3, 2], fwd, atol=1e-9)  # optical axis = heading
        np.testing.assert_allclose(c2w[i, :3, 1], [0, 0, -1], atol=1e-9)  # image down = world down
        np.testing.assert_allclose(c2w[i, :3, 3], base[i, :3, 3] + 0.3 * fwd + [0, 0, 0.05], atol=1e-9)


def test_task_cameras_and_pose_error():
    """The tasks' cameras: the Panda's wrist camera (identity offset at the TCP), the Go2's head camera
    (the mount of test_head_camera_on_the_go2_base), a scaled copy, and the camera pose error."""
    from splatplan.render.cameras import camera_pose_error, head_camera, wrist_camera

    robots = pytest.importorskip("splatplan.robots")
    try:
        panda, go2 = robots.load_robot("panda"), robots.load_robot("go2")
    except Exception as exc:  # pragma: no cover - robot assets missing
        pytest.skip(f"robots not loadable: {exc}")
    w = wrist_camera(panda, image_size=32, fov_deg=70.0)
    assert (w.link_name, w.width, w.height) == ("panda_hand_tcp", 32, 32)
    np.testing.assert_array_equal(w.offset, np.eye(4))
    np.testing.assert_allclose(w.K, intrinsics_from_fov(70.0, 32, 32))
    h = head_camera(go2, image_size=16, fov_deg=90.0, offset=(0.3, 0.0, 0.05))
    np.testing.assert_allclose(h.offset, mount_offset((0.3, 0.0, 0.05), forward=(1, 0, 0), up=(0, 0, 1)))
    s = h.scaled(8)
    assert (s.width, s.height) == (8, 8) and h.scaled(16) is h
    np.testing.assert_allclose(s.K, intrinsics_from_fov(90.0, 8, 8), rtol=1e-12)
    with pytest.raises(SplatplanError, match="no link"):
        wrist_camera(go2)
    t = np.eye(4)
    t2 = np.eye(4)
    t2[:3, 3] = [0.03, 0.0, 0.04]
    c, sn = np.cos(np.radians(20.0)), np.sin(np.radians(20.0))
    t2[:3, :3] = [[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]]
    pe, re = camera_pose_error(t2, t)
    assert pe == pytest.approx(0.05) and re == pytest.approx(20.0)
