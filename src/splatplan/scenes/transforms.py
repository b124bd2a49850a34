"""Rigid and similarity transforms of splat scenes.

All functions return a new :class:`Splats` (the input is not modified) with ``info`` and
``source_format`` carried over. Rotations act on the means and on the splat orientations, so
covariances transform as ``Sigma' = R Sigma R^T``; uniform scaling multiplies means and stds.

Higher SH bands (``sh_rest``) are **not rotated**: view-dependent colour of a rotated scene is
approximate. The DC colour is rotation invariant, and collision checking never uses SH.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import SplatplanError
from .splats import Splats, quat_multiply, quat_to_rotmat, rotmat_to_quat

#: The map from the INRIA/COLMAP capture frame (x right, y down, z forward) to a z-up frame
#: (x right, y forward, z up): (x, y, z) -> (x, z, -y), a -90 degree rotation about x.
Y_DOWN_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def as_rotation(rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3x3 matrix, unit wxyz quaternion) from either form.

    Args:
        rotation: a wxyz quaternion (4,) (normalised here) or a 3x3 rotation matrix.

    Raises:
        SplatplanError: wrong shape, zero quaternion, or a matrix that is not a proper rotation.
    """
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape == (4,):
        norm = np.linalg.norm(r)
        if not np.isfinite(norm) or norm < 1e-12:
            raise SplatplanError(f"rotation quaternion must be finite and non-zero, got {r}")
        q = r / norm
        return quat_to_rotmat(q), q
    if r.shape == (3, 3):
        if not np.all(np.isfinite(r)) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
            raise SplatplanError("rotation matrix must be orthonormal with determinant +1")
        return r, rotmat_to_quat(r)
    raise SplatplanError(f"rotation must be a wxyz quaternion (4,) or a 3x3 matrix, got shape {r.shape}")


def apply_rigid(splats: Splats, rotation: np.ndarray, translation: np.ndarray) -> Splats:
    """x -> R x + t for every splat: means rotated and shifted, orientations rotated (q' = q_R q).

    Args:
        splats: the scene.
        rotation: wxyz quaternion (4,) or 3x3 rotation matrix R.
        translation: t, (3,) scene units, in the output frame.
    """
    r, q_r = as_rotation(rotation)
    t = np.asarray(translation, dtype=np.float64).reshape(-1)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise SplatplanError(f"translation must be 3 finite numbers, got {translation!r}")
    means = splats.means.astype(np.float64) @ r.T + t  # (N, 3)
    quats = quat_multiply(q_r, splats.quats)  # (N, 4) wxyz
    quats *= np.where(quats[:, :1] < 0, -1.0, 1.0)
    return replace(splats, means=means, quats=quats, info=dict(splats.info))


def translate(splats: Splats, t: np.ndarray) -> Splats:
    """Shift every mean by t (3,), scene units."""
    return apply_rigid(splats, np.eye(3), t)


def rotate(splats: Splats, rotation: np.ndarray) -> Splats:
    """Rotate the scene about the origin by a wxyz quaternion (4,) or a 3x3 matrix."""
    return apply_rigid(splats, rotation, np.zeros(3))


def scale(splats: Splats, factor: float) -> Splats:
    """Scale the scene about the origin: means and stds multiplied by ``factor`` (> 0)."""
    if not (np.isfinite(factor) and factor > 0):
        raise SplatplanError(f"scale factor must be a finite number > 0, got {factor}")
    return replace(splats, means=splats.means * np.float32(factor), scales=splats.scales * np.float32(factor), info=dict(splats.info))


def y_down_to_z_up(splats: Splats) -> Splats:
    """Re-express a scene from the INRIA/COLMAP y-down frame in a z-up frame.

    Uses :data:`Y_DOWN_TO_Z_UP`: (x, y, z) -> (x, z, -y), so the capture's "down" (+y) becomes
    -z, "forward" (+z) becomes +y, and x is unchanged (a proper rotation, -90 degrees about x).
    """
    return rotate(splats, Y_DOWN_TO_Z_UP)


def normalize_to_unit(splats: Splats) -> tuple[Splats, np.ndarray]:
    """Centre the means' bounding box at the origin and scale its largest side to 1.

    Returns:
        (scene, T): T is the 4x4 similarity (float64) with ``[x'; 1] = T [x; 1]``, i.e.
        ``x' = s (x - c)`` with c the box centre and s = 1 / largest side; stds scale by s.

    Raises:
        SplatplanError: the scene is empty or all means coincide.
    """
    lo, hi = splats.bounds()
    side = float(np.max(hi - lo))
    if not side > 0:
        raise SplatplanError("cannot normalise a scene whose means all coincide (zero-size bounding box)")
    s = 1.0 / side
    c = 0.5 * (lo + hi)
    out = scale(translate(splats, -c), s)
    transform = np.eye(4)
    transform[:3, :3] *= s
    transform[:3, 3] = -s * c
    return out, transform
