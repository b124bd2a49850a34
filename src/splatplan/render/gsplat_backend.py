"""Adapter to ``gsplat.rasterization`` (CUDA only; optional dependency).

Written from gsplat's documented API (v1.x): ``rasterization(means [N,3], quats [N,4] wxyz,
scales [N,3] linear, opacities [N], colors [N,K,3] SH coefficients with sh_degree, viewmats
[C,4,4] world-to-camera, Ks [C,3,3], width, height, near_plane, far_plane, eps2d, sh_degree,
packed, render_mode="RGB+ED", rasterize_mode="classic") -> (colors [C,H,W,4], alphas [C,H,W,1],
meta)``. gsplat evaluates SH at (mean - camera centre), adds 0.5 and clamps at 0, uses pixel
centres at +0.5, OpenCV camera axes and a 0.3 px^2 low-pass: the same conventions as ours.
Known differences from our kernels: gsplat caps alpha at 0.999 (we use INRIA's 0.99) and may
bound splats more tightly, so images agree closely but not bit for bit.
"""

from __future__ import annotations

import numpy as np

from .._warp import resolve_device
from ..errors import SplatplanError
from ..scenes.splats import Splats
from .config import LOW_PASS, SH_C0, RenderResult, check_render_args, resolve_sh_degree, scene_sh_degree, thickened_scales


def gsplat_available() -> bool:
    """True when gsplat imports and torch sees a CUDA device."""
    try:
        import gsplat  # noqa: F401
        import torch
    except Exception:
        return False
    return bool(torch.cuda.is_available())


class GsplatRenderer:
    """Scene tensors on the GPU for repeated ``gsplat.rasterization`` calls (same API as SplatRenderer.render)."""

    def __init__(self, scene: Splats, device: str | None = "auto") -> None:
        try:
            import gsplat
            import torch
        except Exception as exc:
            raise SplatplanError(
                f"backend 'gsplat' needs the gsplat package and CUDA ({exc.__class__.__name__}: {exc}); "
                "install it with pip install gsplat, or use backend='warp'"
            ) from None
        dev = resolve_device(device)
        if not dev.startswith("cuda") or not torch.cuda.is_available():
            raise SplatplanError("backend 'gsplat' renders on CUDA only; use backend='warp' on the CPU")
        self._gsplat = gsplat
        self._torch = torch
        self.device = dev
        self.n = len(scene)
        if self.n:
            scene.validate()
        scales = thickened_scales(scene.scales)  # (N, 3) same disk thickness as our kernels
        self.sh_degree = scene_sh_degree(scene.sh_rest)
        k_rest = (self.sh_degree + 1) ** 2 - 1
        sh0 = (scene.colors.astype(np.float64) - 0.5) / SH_C0  # colours = 0.5 + C0 * sh0
        coeffs = sh0[:, None, :]
        if k_rest and scene.sh_rest is not None:  # (k_rest > 0: the scene has its SH bands)
            coeffs = np.concatenate([coeffs, scene.sh_rest[:, :k_rest].astype(np.float64)], axis=1)  # (N, K, 3)
        q = scene.quats.astype(np.float64)
        q = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-30) if self.n else q

        def t(a):
            return torch.as_tensor(np.ascontiguousarray(a, dtype=np.float32), device=dev)

        self._means, self._quats, self._scales = t(scene.means), t(q), t(scales)
        self._opac, self._coeffs = t(scene.opacities), t(coeffs)

    def render(self, viewmats, Ks, width: int, height: int, *, near: float = 0.01, far: float = 1e10,
               background=(0.0, 0.0, 0.0), sh_degree: int | None = None) -> RenderResult:  # fmt: skip
        torch = self._torch
        v, k, width, height, near, far, bg = check_render_args(viewmats, Ks, width, height, near, far, background)
        deg = resolve_sh_degree(sh_degree, self.sh_degree)
        b = v.shape[0]
        dev = self.device
        bg_t = torch.as_tensor(bg, dtype=torch.float32, device=dev)
        if self.n == 0 or b == 0:
            rgb = bg_t.expand(b, height, width, 3).contiguous()
            zero = torch.zeros((b, height, width), dtype=torch.float32, device=dev)
            return _convert(rgb, zero, zero.clone(), viewmats)
        colors, alphas, _ = self._gsplat.rasterization(
            means=self._means, quats=self._quats, scales=self._scales, opacities=self._opac,
            colors=self._coeffs[:, : (deg + 1) ** 2], viewmats=torch.as_tensor(v, dtype=torch.float32, device=dev),
            Ks=torch.as_tensor(k, dtype=torch.float32, device=dev), width=width, height=height,
            near_plane=near, far_plane=far, eps2d=LOW_PASS, sh_degree=deg, packed=False,
            render_mode="RGB+ED", rasterize_mode="classic",
        )  # fmt: skip
        alpha = alphas[..., 0]
        rgb = colors[..., :3] + (1.0 - alpha)[..., None] * bg_t
        depth = torch.where(alpha > 0, colors[..., 3], torch.zeros_like(alpha))
        return _convert(rgb, depth, alpha, viewmats)


def _convert(rgb, depth, alpha, like) -> RenderResult:
    if type(like).__module__.startswith("torch"):
        return RenderResult(rgb, depth, alpha)
    return RenderResult(rgb.cpu().numpy(), depth.cpu().numpy(), alpha.cpu().numpy())
