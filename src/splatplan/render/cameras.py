"""Cameras: one :class:`Camera` type, look-at and field-of-view helpers, robot-mounted cameras.

Frames: a camera's ``viewmat`` is the (4, 4) **world-to-camera** rigid transform, OpenCV axes
(x right, y down, z forward); ``K`` the (3, 3) pixel intrinsics, pixel centres at +0.5.
A :class:`MountedCamera` sits on a robot link at a fixed ``offset`` = link <- camera (4, 4),
the camera frame again in OpenCV axes; :func:`mount_offset` builds one from a position and a
viewing direction given in the link frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["Camera", "MountedCamera", "camera_pose_error", "head_camera", "look_at", "intrinsics_from_fov", "mount_offset", "invert_rigid", "wrist_camera"]


def invert_rigid(t: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4) (rotation transposed, no general inverse)."""
    t = np.asarray(t, dtype=np.float64)
    r = np.swapaxes(t[..., :3, :3], -1, -2)
    out = np.zeros_like(t)
    out[..., :3, :3] = r
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", r, t[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def _camera_rotation(forward: np.ndarray, up: np.ndarray, what: str) -> np.ndarray:
    """(..., 3, 3) rows = camera x (right), y (down), z (forward) axes in the input frame."""
    f = forward / np.linalg.norm(forward, axis=-1, keepdims=True)
    right = np.cross(f, up)
    nr = np.linalg.norm(right, axis=-1, keepdims=True)
    if np.any(nr < 1e-9):
        raise SplatplanError(f"{what}: the viewing direction is parallel to 'up'; pass another up vector")
    right = right / nr
    down = np.cross(f, right)
    return np.stack([right, down, f], axis=-2)


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """World-to-camera (OpenCV) matrices of cameras at ``eye`` looking at ``target``.

    Args:
        eye, target: (..., 3) world points (broadcast together).
        up: (3,) or (..., 3) world direction that appears up in the image (default +z).

    Returns:
        (..., 4, 4) float64 world-to-camera transforms: camera z along target - eye, x to the
        right of it, y down (image rows grow downwards).
    """
    eye = np.asarray(eye, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    up = np.asarray(up, dtype=np.float64)
    for name, a in (("eye", eye), ("target", target), ("up", up)):
        if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)):
            raise SplatplanError(f"look_at: {name} must be finite (..., 3) points, got shape {a.shape}")
    fwd = target - eye
    if np.any(np.linalg.norm(fwd, axis=-1) < 1e-12):
        raise SplatplanError("look_at: eye and target coincide")
    if np.any(np.linalg.norm(up, axis=-1) < 1e-12):
        raise SplatplanError("look_at: up is a zero vector")
    fwd, up_b = np.broadcast_arrays(fwd, up)
    rot = _camera_rotation(fwd, up_b, "look_at")  # (..., 3, 3) world -> camera
    eye_b = np.broadcast_to(eye, fwd.shape)
    out = np.zeros(fwd.shape[:-1] + (4, 4))
    out[..., :3, :3] = rot
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rot, eye_b)
    out[..., 3, 3] = 1.0
    return out


#: the narrowest and widest field of view a pinhole camera takes (degrees)
MIN_FOV_DEG, MAX_FOV_DEG = 0.01, 179.0


def intrinsics_from_fov(fov_deg: float, width: int, height: int, axis: str = "horizontal") -> np.ndarray:
    """(3, 3) pinhole intrinsics with square pixels and the principal point at the image centre.

    Args:
        fov_deg: full field of view in degrees, in (0, 180), along ``axis``.
        width, height: image size in pixels.
        axis: "horizontal" (fov spans the width) or "vertical" (spans the height).
    """
    fov = float(fov_deg)
    if not (np.isfinite(fov) and MIN_FOV_DEG <= fov <= MAX_FOV_DEG):  # beyond: focal lengths overflow float32
        raise SplatplanError(f"field of view must be in [{MIN_FOV_DEG:g}, {MAX_FOV_DEG:g}] degrees, got {fov_deg}")
    if int(width) <= 0 or int(height) <= 0:
        raise SplatplanError(f"image size must be positive, got {width}x{height}")
    if axis not in ("horizontal", "vertical"):
        raise SplatplanError(f"axis must be 'horizontal' or 'vertical', got {axis!r}")
    span = width if axis == "horizontal" else height
    f = 0.5 * span / np.tan(np.radians(fov) / 2.0)
    return np.array([[f, 0.0, 0.5 * width], [0.0, f, 0.5 * height], [0.0, 0.0, 1.0]])


def mount_offset(position=(0.0, 0.0, 0.0), forward=(0.0, 0.0, 1.0), up=(0.0, -1.0, 0.0)) -> np.ndarray:
    """link <- camera (4, 4) for a camera at ``position`` (link frame) looking along ``forward``
    with ``up`` appearing up in its image (both link-frame directions).

    The default is the identity: the OpenCV camera axes coincide with the link's axes (camera
    looks along link +z, image up is link -y). A head camera on a base whose +x is forward and
    +z up: ``mount_offset((0.3, 0, 0.05), forward=(1, 0, 0), up=(0, 0, 1))``.
    """
    p = np.asarray(position, dtype=np.float64)
    f = np.asarray(forward, dtype=np.float64)
    u = np.asarray(up, dtype=np.float64)
    if p.shape != (3,) or f.shape != (3,) or u.shape != (3,) or not np.all(np.isfinite(np.concatenate([p, f, u]))):
        raise SplatplanError("mount_offset: position, forward and up must be three finite numbers each")
    if np.linalg.norm(f) < 1e-12 or np.linalg.norm(u) < 1e-12:
        raise SplatplanError("mount_offset: forward and up must be non-zero")
    rot = _camera_rotation(f, u, "mount_offset")  # rows: camera axes in the link frame
    out = np.eye(4)
    out[:3, :3] = rot.T  # columns = camera axes in the link frame: link <- camera
    out[:3, 3] = p
    return out


@dataclass
class Camera:
    """One pinhole camera.

    Attributes:
        viewmat: (4, 4) float64 world-to-camera (OpenCV axes).
        K: (3, 3) float64 pixel intrinsics.
        width, height: image size in pixels.
    """

    viewmat: np.ndarray
    K: np.ndarray
    width: int
    height: int

    def __post_init__(self) -> None:
        from .config import check_cameras, check_image_size

        self.width, self.height = check_image_size(self.width, self.height)
        v, k = check_cameras(self.viewmat, self.K)
        if v.shape[0] != 1:
            raise SplatplanError(f"Camera takes one (4, 4) viewmat, got {np.shape(self.viewmat)}")
        self.viewmat, self.K = v[0], k[0]

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 0.0, 1.0), *, fov_deg: float = 60.0, width: int = 256, height: int = 256) -> "Camera":
        """A camera at ``eye`` looking at ``target`` with a horizontal field of view ``fov_deg``."""
        return cls(look_at(eye, target, up), intrinsics_from_fov(fov_deg, width, height), width, height)

    @property
    def position(self) -> np.ndarray:
        """(3,) camera centre, world frame."""
        return invert_rigid(self.viewmat)[:3, 3]

    @property
    def cam_to_world(self) -> np.ndarray:
        """(4, 4) world <- camera."""
        return invert_rigid(self.viewmat)

    @staticmethod
    def stack(cameras: "list[Camera]") -> tuple[np.ndarray, np.ndarray, int, int]:
        """(viewmats (B, 4, 4), Ks (B, 3, 3), width, height) of cameras sharing one image size."""
        if not cameras:
            raise SplatplanError("no cameras to stack")
        w, h = cameras[0].width, cameras[0].height
        if any((c.width, c.height) != (w, h) for c in cameras):
            raise SplatplanError("cameras rendered in one batch must share one image size")
        return np.stack([c.viewmat for c in cameras]), np.stack([c.K for c in cameras]), w, h


@dataclass
class MountedCamera:
    """A camera rigidly attached to a robot link.

    Attributes:
        link_name: the robot link carrying it (one of ``robot.link_names``).
        offset: (4, 4) link <- camera (OpenCV camera axes), see :func:`mount_offset`.
        K: (3, 3) pixel intrinsics.
        width, height: image size in pixels.
    """

    link_name: str
    offset: np.ndarray = field(default_factory=lambda: np.eye(4))
    K: np.ndarray = field(default_factory=lambda: intrinsics_from_fov(60.0, 64, 64))
    width: int = 64
    height: int = 64

    def __post_init__(self) -> None:
        from .config import check_cameras, check_image_size

        self.width, self.height = check_image_size(self.width, self.height)
        off = np.asarray(self.offset, dtype=np.float64)
        if off.shape != (4, 4):
            raise SplatplanError(f"MountedCamera offset must be (4, 4) link <- camera, got {off.shape}")
        check_cameras(invert_rigid(off) if np.all(np.isfinite(off)) else off, self.K)  # rigid + K valid
        self.offset = off
        self.K = np.asarray(self.K, dtype=np.float64)

    def scaled(self, width: int) -> "MountedCamera":
        """This camera at ``width`` pixels wide, same field of view and aspect (itself when already so)."""
        if self.width == width:
            return self
        s = width / self.width
        k = np.asarray(self.K, np.float64).copy()
        k[:2] *= s
        return MountedCamera(self.link_name, self.offset, k, width, max(1, round(self.height * s)))

    def _link_index(self, robot) -> int:
        names = list(robot.link_names)
        if self.link_name not in names:
            raise SplatplanError(f"robot {getattr(robot, 'name', '?')!r} has no link {self.link_name!r}; links: {', '.join(names)}")
        return names.index(self.link_name)

    def cam_to_world(self, robot: Robot, q) -> np.ndarray:
        """(..., 4, 4) world <- camera for configurations q (..., dof)."""
        poses = np.asarray(robot.link_poses(q), dtype=np.float64)  # (..., L, 4, 4) world <- link
        return poses[..., self._link_index(robot), :, :] @ self.offset

    def viewmats(self, robot: Robot, q) -> np.ndarray:
        """(..., 4, 4) world-to-camera matrices for configurations q (..., dof), e.g. (K, dof) rollouts."""
        return invert_rigid(self.cam_to_world(robot, q))

    def Ks(self, batch_shape: tuple[int, ...]) -> np.ndarray:
        """(*batch_shape, 3, 3) copies of K."""
        return np.broadcast_to(self.K, tuple(batch_shape) + (3, 3)).copy()

    def render(self, renderer, robot: Robot, q, **kwargs):
        """Render the views at configurations q (K, dof) with a :class:`SplatRenderer` (or anything
        with its ``render`` signature). Returns its :class:`RenderResult` (K images)."""
        v = self.viewmats(robot, q).reshape(-1, 4, 4)
        return renderer.render(v, self.Ks((v.shape[0],)), self.width, self.height, **kwargs)


def wrist_camera(robot: Robot, image_size: int = 64, fov_deg: float = 70.0, link: str = "panda_hand_tcp"):
    """The wrist camera: a :class:`~splatplan.render.MountedCamera` at ``link`` (identity offset:
    the camera looks along the link's z axis, image x along link x)."""
    cam = MountedCamera(link, np.eye(4), intrinsics_from_fov(fov_deg, image_size, image_size), image_size, image_size)
    cam._link_index(robot)
    return cam


def camera_pose_error(t: np.ndarray, t_goal: np.ndarray) -> tuple[float, float]:
    """(translation error m, rotation error deg) between camera poses world <- camera (4, 4)."""
    pe = float(np.linalg.norm(t[:3, 3] - t_goal[:3, 3]))
    c = 0.5 * (np.trace(t_goal[:3, :3].T @ t[:3, :3]) - 1.0)
    return pe, float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def head_camera(robot: Robot, image_size: int = 64, fov_deg: float = 90.0, offset=(0.30, 0.0, 0.05), link: str = "base"):
    """A legged robot's head camera: a :class:`MountedCamera` on ``link`` at ``offset`` (m, link
    frame: x forward, y left, z up), looking along the link's +x, image up = +z."""
    cam = MountedCamera(link, mount_offset(tuple(offset), forward=(1.0, 0.0, 0.0), up=(0.0, 0.0, 1.0)), intrinsics_from_fov(fov_deg, image_size, image_size), image_size, image_size)
    cam._link_index(robot)
    return cam
