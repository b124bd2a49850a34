"""Per-splat orientation and the floor's surface: what scene alignment and terrain both read.

* :func:`splat_normals` - each splat's normal (the world axis of its smallest std) and whether it
  is flat (smallest std < 0.3x the middle one): the plane fit of :mod:`~splatplan.scenes.align`
  reads them, and so does the floor mask below.
* :func:`floor_surface_mask` - the floor-like splats of the step band of a z-up scene (flat, normal
  near +z, mean below ``floor_z + step_height``): terrain at every n_sigma
  (:mod:`~splatplan.scenes.terrain`) and left out of the floater test of ``scene align
  --drop-floaters`` (:func:`~splatplan.scenes.align.align_scene`).

A leaf of the scene stage: it imports only the :class:`~splatplan.scenes.splats.Splats` container.
"""

from __future__ import annotations

import numpy as np

from .splats import Splats, quat_to_rotmat

__all__ = ["floor_surface_mask", "splat_normals"]


def splat_normals(splats: Splats) -> tuple[np.ndarray, np.ndarray]:
    """(normals (N, 3) world axis of each splat's smallest std, flat (N,) bool: smallest < 0.3x middle)."""
    s = splats.scales.astype(np.float64)
    r = quat_to_rotmat(splats.quats)
    k = np.argmin(s, axis=1)
    normals = r[np.arange(len(s)), :, k]
    ss = np.sort(s, axis=1)
    return normals, ss[:, 0] < 0.3 * ss[:, 1]


def floor_surface_mask(splats: Splats, floor_z: float, step_height: float, max_tilt_deg: float = 30.0) -> np.ndarray:
    """(N,) bool: the terrain splats at **every** n_sigma: the floor-like ones (flat, normal within
    ``max_tilt_deg`` of +z) with their mean below ``floor_z + step_height``. The other splats of the
    step band (upright or round ones whose n_sigma extent may reach above it) are obstacles at a
    large enough n_sigma, so the floater rule of ``scene align --drop-floaters`` tests them too."""
    z = splats.means[:, 2].astype(np.float64)
    normals, flat = splat_normals(splats)
    return (z < floor_z + step_height) & flat & (np.abs(normals[:, 2]) >= np.cos(np.radians(max_tilt_deg)))
