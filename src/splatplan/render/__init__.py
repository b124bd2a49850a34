"""Rendering stage: a tile rasteriser for Gaussian splats (Warp kernels on CPU and CUDA, gsplat
on CUDA when installed), its numpy reference, and cameras (look-at, field of view, robot-mounted).

    from splatplan.render import SplatRenderer, render
    res = render(scene, viewmats, Ks, 64, 64)                   # one-off
    with SplatRenderer(scene, "cpu") as r:                      # repeated calls (MPPI)
        res = r.render(viewmats, Ks, 64, 64)

``splatplan.render`` is this package; the function is :func:`splatplan.render.render`.

Conventions: ``docs/rendering.md`` and :mod:`.config`.
"""

from __future__ import annotations

from .api import render
from .cameras import Camera, MountedCamera, camera_pose_error, head_camera, intrinsics_from_fov, look_at, mount_offset, wrist_camera
from .config import RenderResult
from .renderer import SplatRenderer

__all__ = ["render", "RenderResult", "SplatRenderer", "Camera", "MountedCamera", "camera_pose_error", "head_camera", "look_at", "intrinsics_from_fov", "mount_offset", "wrist_camera"]

