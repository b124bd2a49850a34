"""The functional entry point :func:`render`."""

from __future__ import annotations

from ..errors import SplatplanError
from ..scenes.splats import Splats
from .config import MAX_BYTES, RenderResult

BACKENDS = ("auto", "warp", "gsplat", "reference")


def render(
    scene: Splats, viewmats, Ks, width: int, height: int, *, near: float = 0.01, far: float = 1e10, background=(0.0, 0.0, 0.0),
    sh_degree: int | None = None, device: str | None = "auto", backend: str = "auto", max_bytes: int = MAX_BYTES
) -> RenderResult:
    """Render a splat scene from a batch of B pinhole cameras.

    Args:
        scene: the splats (:class:`splatplan.Splats`; an empty scene renders the background).
        viewmats: (B, 4, 4) or (4, 4) **world-to-camera** rigid transforms, OpenCV camera axes
            (x right, y down, z forward). numpy, torch or Warp arrays.
        Ks: (B, 3, 3) or (3, 3) pixel intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; pixel
            (u, v) has its centre at (u + 0.5, v + 0.5), so cx = width / 2 is the image centre.
        width, height: image size in pixels.
        near, far: splats whose mean has view depth z outside [near, far] are culled.
        background: RGB composited as rgb + (1 - alpha) * background.
        sh_degree: SH bands to evaluate (None: every band the scene has; larger values are
            clamped to the scene's degree).
        device: "cpu", "cuda", "cuda:N" or None/"auto" (CUDA when present).
        backend: "auto" / "warp" (our Warp kernels, any device), "gsplat" (``gsplat.rasterization``;
            CUDA and the gsplat package needed) or "reference" (numpy, slow, for tests).
        max_bytes: cap on the memory of one call (outputs + workspace), default 2 GiB.

    Returns:
        :class:`RenderResult` with rgb (B, H, W, 3), depth (B, H, W) (expected view depth of the
        splat means, 0 where nothing was hit) and alpha (B, H, W), float32. numpy unless the
        viewmats came as torch tensors or Warp arrays.

    For repeated calls on one scene (e.g. every MPPI iteration) keep a
    :class:`~splatplan.render.SplatRenderer`: it uploads the scene once and owns the thread pool.
    """
    if backend not in BACKENDS:
        raise SplatplanError(f"unknown render backend {backend!r}: use one of {', '.join(BACKENDS)}")
    if backend == "reference":
        from .reference import render_reference

        return render_reference(scene, viewmats, Ks, width, height, near=near, far=far, background=background, sh_degree=sh_degree)
    if backend == "gsplat":
        from .gsplat_backend import GsplatRenderer

        r = GsplatRenderer(scene, device=device)
        return r.render(viewmats, Ks, width, height, near=near, far=far, background=background, sh_degree=sh_degree)
    from .renderer import SplatRenderer

    with SplatRenderer(scene, device, max_bytes=max_bytes) as r:
        return r.render(viewmats, Ks, width, height, near=near, far=far, background=background, sh_degree=sh_degree)
