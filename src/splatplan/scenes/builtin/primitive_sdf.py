"""Primitive rows (box, cylinder, sphere) and their exact signed distances, in numpy.

Units and frames
----------------
* Coordinates are in *scene units* in the scene's world frame (z up for the built-in scenes).
* A box row is ``(cx, cy, cz, hx, hy, hz, qw, qx, qy, qz)``: centre (world), half-extents along
  the box's own x/y/z axes, and a **wxyz** unit quaternion rotating the box frame into the world
  frame (``p_world = R @ p_box + c``).
* A cylinder row is ``(cx, cy, cz, radius, half_height, qw, qx, qy, qz)``: centre (world), radius,
  half of its height along the cylinder's own **z** axis, wxyz quaternion cylinder -> world
  (MoveIt's ``cylinder`` primitive ``[height, radius]``, axis along the object's z).
* A sphere row is ``(cx, cy, cz, radius)``.

The single-primitive functions (:func:`box_sdf`, :func:`cylinder_sdf`, :func:`sphere_sdf`) are the
slow, obviously-correct references; :func:`boxes_sdf_dense` and :func:`curved_sdf` are the batched
forms :class:`~.analytic_scene.AnalyticScene` uses.
"""

from __future__ import annotations

import numpy as np

from ...errors import SplatplanError
from ..splats import quat_to_rotmat

__all__ = [
    "box_corners", "box_sdf", "box_sdf_local", "boxes_sdf_dense", "curved_sdf", "cylinder_sdf", "cylinder_sdf_local",
    "make_box", "make_cylinder", "make_sphere", "sphere_sdf", "yaw_quat",
]  # fmt: skip


def make_box(
    center,  # (3,) world
    half_extents,  # (3,) box frame
    quat=(1.0, 0.0, 0.0, 0.0),  # (4,) wxyz, box -> world
) -> np.ndarray:
    """One box row ``(c, h, q)`` as float64 (10,), with the quaternion normalised (w >= 0)."""
    q = np.asarray(quat, dtype=np.float64)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-12:
        raise SplatplanError(f"make_box: quaternion {quat!r} is zero or not finite")
    q = q / n
    if q[0] < 0:
        q = -q
    return np.concatenate([np.asarray(center, np.float64), np.asarray(half_extents, np.float64), q])


def make_cylinder(
    center,  # (3,) world
    radius: float,
    half_height: float,  # along the cylinder's own z axis
    quat=(1.0, 0.0, 0.0, 0.0),  # (4,) wxyz, cylinder -> world
) -> np.ndarray:
    """One cylinder row ``(c, radius, half_height, q)`` as float64 (9,), quaternion normalised (w >= 0)."""
    b = make_box(center, (radius, radius, half_height), quat)
    return np.concatenate([b[:3], [float(radius), float(half_height)], b[6:10]])


def make_sphere(center, radius: float) -> np.ndarray:  # center (3,) world
    """One sphere row ``(c, radius)`` as float64 (4,)."""
    return np.concatenate([np.asarray(center, np.float64).reshape(3), [float(radius)]])


def yaw_quat(yaw: float) -> np.ndarray:
    """wxyz (4,) rotation by ``yaw`` (rad) about +z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def box_sdf(
    points: np.ndarray,  # (P, 3) world
    box: np.ndarray,  # (10,) c, h, q(wxyz)
) -> np.ndarray:
    """Exact signed distance (P,) float64 from ``points`` to one solid box (negative inside).

    This is the slow, obviously-correct single-box reference used by the tests.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    c, h, q = box[:3], box[3:6], box[6:10]
    rot = quat_to_rotmat(q)  # (3, 3) box -> world
    local = (p - c) @ rot  # (P, 3) = R^T (p - c)
    d = np.abs(local) - h  # (P, 3)
    outside = np.linalg.norm(np.maximum(d, 0.0), axis=1)
    inside = np.minimum(d.max(axis=1), 0.0)
    return outside + inside


def cylinder_sdf(
    points: np.ndarray,  # (P, 3) world
    cyl: np.ndarray,  # (9,) c, radius, half_height, q(wxyz)
) -> np.ndarray:
    """Exact signed distance (P,) float64 from ``points`` to one solid cylinder (negative inside).

    Slow, obviously-correct reference: in the cylinder frame the solid is the product of a disk of
    radius r (x, y) and a segment |z| <= h, so with ``d = (|p_xy| - r, |p_z| - h)`` the distance is
    ``|max(d, 0)| + min(max(d), 0)`` (the 2-D box formula in the (radial, axial) half-plane).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rot = quat_to_rotmat(cyl[5:9])
    local = (p - cyl[:3]) @ rot  # (P, 3)
    d = np.stack([np.hypot(local[:, 0], local[:, 1]) - cyl[3], np.abs(local[:, 2]) - cyl[4]], axis=1)
    return np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)


def sphere_sdf(
    points: np.ndarray,  # (P, 3) world
    sph: np.ndarray,  # (4,) c, radius
) -> np.ndarray:
    """Exact signed distance (P,) float64 from ``points`` to one solid sphere (negative inside)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return np.linalg.norm(p - sph[:3], axis=1) - sph[3]


def cylinder_sdf_local(p: np.ndarray, prm: np.ndarray) -> np.ndarray:
    """Cylinder SDF for points p (..., 3) in the cylinder frame, prm (..., 2) = (radius, half_height)."""
    d0 = np.sqrt(p[..., 0] ** 2 + p[..., 1] ** 2) - prm[..., 0]
    d1 = np.abs(p[..., 2]) - prm[..., 1]
    return np.sqrt(np.maximum(d0, 0.0) ** 2 + np.maximum(d1, 0.0) ** 2) + np.minimum(np.maximum(d0, d1), 0.0)


def box_sdf_local(p: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Box SDF for points p (..., 3) in the box frame, half-extents h broadcast (..., 3)."""
    d = np.abs(p) - h
    return np.linalg.norm(np.maximum(d, 0.0), axis=-1) + np.minimum(d.max(axis=-1), 0.0)


def curved_sdf(
    p: np.ndarray,  # (P, 3) float64 world
    cylinders: np.ndarray,  # (C, 9)
    spheres: np.ndarray,  # (S, 4)
    chunk: int | None = None,
) -> np.ndarray:
    """min over the cylinders and spheres of their exact SDFs, (P,) float64 (inf when there are none)."""
    out = np.full(p.shape[0], np.inf)
    n = len(cylinders) + len(spheres)
    if n == 0 or p.shape[0] == 0:
        return out
    if chunk is None:
        chunk = max(256, int(1_000_000 // (3 * n)))
    rot = quat_to_rotmat(cylinders[:, 5:9]).reshape(-1, 3, 3) if len(cylinders) else np.zeros((0, 3, 3))
    for s in range(0, p.shape[0], chunk):
        ps = p[s : s + chunk]
        if len(cylinders):
            local = np.einsum("cmj,mji->cmi", ps[:, None, :] - cylinders[None, :, :3], rot)  # (P', C, 3) = R^T (p - c)
            out[s : s + chunk] = np.minimum(out[s : s + chunk], cylinder_sdf_local(local, cylinders[None, :, 3:5]).min(axis=1))
        if len(spheres):
            d = np.linalg.norm(ps[:, None, :] - spheres[None, :, :3], axis=2) - spheres[None, :, 3]  # (P', S)
            out[s : s + chunk] = np.minimum(out[s : s + chunk], d.min(axis=1))
    return out


def box_corners(box: np.ndarray) -> np.ndarray:
    """The 8 world-frame corners of a box, float64 (8, 3) (index bits: x, y, z sign)."""
    signs = np.array([[(i >> 0) & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], np.float64) * 2 - 1
    rot = quat_to_rotmat(box[6:10])
    return (signs * box[3:6]) @ rot.T + box[:3]


def boxes_sdf_dense(
    p: np.ndarray,  # (P, 3) float64
    boxes: np.ndarray,  # (M, 10)
    rot: np.ndarray,  # (M, 3, 3) box -> world
    chunk: int | None = None,
) -> np.ndarray:
    """min over the boxes of the exact box SDFs, (P,) float64, by brute force in chunks."""
    m = boxes.shape[0]
    out = np.empty(p.shape[0])
    if chunk is None:
        chunk = max(256, int(1_000_000 // (3 * m)))
    # Box-frame coordinates of every point for every box in one GEMM:
    # R_m^T (p - c_m) = p @ R_m - c_m @ R_m, stacked as p @ W - b with W (3, 3M), b (3M,).
    w = rot.transpose(1, 0, 2).reshape(3, 3 * m)
    b = np.einsum("mi,mij->mj", boxes[:, :3], rot).reshape(3 * m)
    h = boxes[:, 3:6][None]  # (1, M, 3)
    for s in range(0, p.shape[0], chunk):
        local = (p[s : s + chunk] @ w - b).reshape(-1, m, 3)  # (C, M, 3) box-frame coordinates
        np.abs(local, out=local)
        local -= h
        inside = np.minimum(local.max(axis=2), 0.0)  # (C, M)
        np.maximum(local, 0.0, out=local)
        outside = np.sqrt(np.einsum("cmi,cmi->cm", local, local))
        out[s : s + chunk] = (outside + inside).min(axis=1)
    return out
