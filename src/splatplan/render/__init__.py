"""Rendering stage: a tile rasteriser for Gaussian splats (Warp kernels on CPU and CUDA, gsplat
on CUDA when installed), its numpy reference, and cameras (look-at, field of view, robot-mounted).

    import splatplan
    res = splatplan.render(scene, viewmats, Ks, 64, 64)         # one-off
    with splatplan.render.SplatRenderer(scene, "cpu") as r:     # repeated calls (MPPI)
        res = r.render(viewmats, Ks, 64, 64)

Conventions: ``docs/rendering.md`` and :mod:`.config`.
"""

from __future__ import annotations

import sys
import types

from .api import render
from .cameras import Camera, MountedCamera, camera_pose_error, head_camera, intrinsics_from_fov, look_at, mount_offset, wrist_camera
from .config import RenderResult
from .renderer import SplatRenderer

__all__ = ["render", "RenderResult", "SplatRenderer", "Camera", "MountedCamera", "camera_pose_error", "head_camera", "look_at", "intrinsics_from_fov", "mount_offset", "wrist_camera"]


class _CallableModule(types.ModuleType):
    """``splatplan.render`` is both this package and the function: importing the package makes
    Python bind the package to the attribute ``splatplan.render``, so the package forwards calls
    to :func:`render` and ``splatplan.render(scene, viewmats, Ks, w, h)`` always works."""

    def __call__(self, *args, **kwargs):
        return render(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
