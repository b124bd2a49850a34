"""Rendering conventions in one place: constants shared by the kernels and the reference,
the result type, and validation of camera batches.

Conventions (see ``docs/rendering.md``):

* ``viewmats`` (B, 4, 4) are **world-to-camera** rigid transforms; camera axes are OpenCV's
  (x right, y down, z forward). ``Ks`` (B, 3, 3) are pixel intrinsics [[fx, 0, cx], [0, fy, cy],
  [0, 0, 1]]; pixel (u, v) (column, row) has its centre at (u + 0.5, v + 0.5).
* Splat colour = SH at the viewing direction (mean - camera centre, normalised), every band the
  scene has up to ``sh_degree``, + 0.5 (folded into ``Splats.colors``), clamped at 0.
* Rasterisation follows the INRIA rasteriser / gsplat "classic": EWA projection
  J W Sigma W^T J^T plus ``LOW_PASS`` px^2 on the diagonal, 16x16 tiles, front-to-back by the
  view depth of the mean, alpha = min(``ALPHA_MAX``, o exp(-0.5 d^T Sigma2D^-1 d)),
  contributions below ``ALPHA_MIN`` skipped, a pixel stops before the splat that would take its
  transmittance below ``T_MIN``.
* Outputs: ``rgb`` = sum w_i c_i + T bg, ``alpha`` = 1 - T, ``depth`` = sum w_i z_i / alpha
  (expected view depth of the means, 0 where alpha = 0), w_i = alpha_i T_i.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._arrays import host_array
from ..errors import SplatplanError

#: Tile side in pixels (binning unit of the rasteriser).
TILE = 16
#: Added to the diagonal of every projected 2D covariance (px^2): the anti-aliasing low-pass.
LOW_PASS = 0.3
#: Per-splat alpha cap (INRIA's 0.99).
ALPHA_MAX = 0.99
#: Contributions with alpha below this are skipped (1/255).
ALPHA_MIN = 1.0 / 255.0
#: A pixel stops before a splat would take its transmittance below this.
T_MIN = 1e-4
#: Guard band of the EWA Jacobian: x/z, y/z are clamped to the image edge plus this fraction of
#: the half field of view (gsplat / INRIA use 0.3, i.e. 1.3 x tan(fov/2) for a centred camera).
GUARD = 0.3
#: 2DGS disks (third std exactly 0) are rendered as flat 3D Gaussians with this third std,
#: relative to the disk's larger std (their projection would otherwise be singular edge-on
#: without the low-pass).
DISK_THICKNESS = 1e-3
#: Default cap on the memory one render call may take (outputs + workspace), bytes.
MAX_BYTES = 2 * 1024**3
#: Largest accepted image side in pixels.
MAX_SIDE = 16384

SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
SH_C3 = (
    -0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
    -0.4570457994644658, 1.445305721320277, -0.5900435899266435,
)  # fmt: skip


@dataclass
class RenderResult:
    """Images of a batch of B cameras.

    Attributes:
        rgb: (B, H, W, 3) float32 colour with the background composited: rgb + (1 - alpha) * bg.
        depth: (B, H, W) float32 expected view depth (scene units along the camera z axis) of the
            splat means, sum w_i z_i / sum w_i; 0 where nothing was hit (alpha = 0).
        alpha: (B, H, W) float32 accumulated opacity 1 - T.

    The arrays are numpy unless the cameras came as torch tensors (then torch, on the render
    device) or Warp arrays (then Warp arrays on the render device, rgb as wp.vec3 (B, H, W)).
    """

    rgb: Any  # numpy, torch or Warp array (see above)
    depth: Any
    alpha: Any

    def __len__(self) -> int:
        return int(self.rgb.shape[0])


def thickened_scales(scales: np.ndarray) -> np.ndarray:
    """(N, 3) float64 copy of the linear stds with 2DGS disks (third std 0) given the third std
    ``DISK_THICKNESS`` x their larger std (every backend renders disks this way)."""
    out = np.asarray(scales, dtype=np.float64).copy()
    disk = out[:, 2] == 0
    out[disk, 2] = DISK_THICKNESS * out[disk, :2].max(axis=1)
    return out


def scene_sh_degree(sh_rest: np.ndarray | None) -> int:
    """Highest complete SH degree (<= 3) that ``sh_rest`` (N, K, 3) holds."""
    k = 0 if sh_rest is None else int(sh_rest.shape[1])
    deg = 0
    while deg < 3 and (deg + 2) ** 2 - 1 <= k:
        deg += 1
    return deg


def resolve_sh_degree(sh_degree: int | None, scene_degree: int) -> int:
    """``None`` -> every band the scene has; an int in [0, 3] is clamped to the scene's degree."""
    if sh_degree is None:
        return scene_degree
    if not isinstance(sh_degree, (int, np.integer)) or not 0 <= int(sh_degree) <= 3:
        raise SplatplanError(f"sh_degree must be None or an integer in 0..3, got {sh_degree!r}")
    return min(int(sh_degree), scene_degree)


def _to_numpy(x, what: str) -> np.ndarray:
    try:
        arr = np.asarray(host_array(x), dtype=np.float64)
    except (TypeError, ValueError):
        raise SplatplanError(f"{what} must be a numeric array") from None
    return arr


def check_image_size(width, height) -> tuple[int, int]:
    """Validate the image size: positive integers no larger than ``MAX_SIDE``."""
    out = []
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) and not (isinstance(v, float) and v.is_integer()):
            raise SplatplanError(f"image {name} must be an integer number of pixels, got {v!r}")
        v = int(v)
        if v <= 0:
            raise SplatplanError(f"image {name} must be >= 1 pixel, got {v}")
        if v > MAX_SIDE:
            raise SplatplanError(f"image {name} {v} exceeds the largest supported side {MAX_SIDE} px")
        out.append(v)
    return out[0], out[1]


def check_cameras(viewmats, Ks) -> tuple[np.ndarray, np.ndarray]:
    """Validate a camera batch. Returns float64 viewmats (B, 4, 4) and Ks (B, 3, 3).

    Accepts (4, 4) / (3, 3) for a single camera; a single K broadcasts over the viewmats.
    Raises :class:`SplatplanError` for non-finite values, non-rigid or singular viewmats, a last
    row other than [0, 0, 0, 1], and intrinsics that are not [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    with finite fx, fy > 0.
    """
    v = _to_numpy(viewmats, "viewmats")
    k = _to_numpy(Ks, "Ks")
    if v.ndim == 2:
        v = v[None]
    if k.ndim == 2:
        k = k[None]
    if v.ndim != 3 or v.shape[1:] != (4, 4):
        raise SplatplanError(f"viewmats must have shape (B, 4, 4) (world-to-camera), got {np.shape(viewmats)}")
    if k.ndim != 3 or k.shape[1:] != (3, 3):
        raise SplatplanError(f"Ks must have shape (B, 3, 3) (pixel intrinsics), got {np.shape(Ks)}")
    b = v.shape[0]
    if k.shape[0] == 1 and b != 1:
        k = np.broadcast_to(k, (b, 3, 3))
    if k.shape[0] != b:
        raise SplatplanError(f"viewmats has {b} cameras but Ks has {k.shape[0]}")
    bad = ~np.isfinite(v).all(axis=(1, 2))
    if bad.any():
        raise SplatplanError(f"viewmats[{int(np.argmax(bad))}] contains NaN or Inf ({int(bad.sum())} camera(s))")
    bad = ~np.isfinite(k).all(axis=(1, 2))
    if bad.any():
        raise SplatplanError(f"Ks[{int(np.argmax(bad))}] contains NaN or Inf ({int(bad.sum())} camera(s))")
    if b == 0:
        return v, np.ascontiguousarray(k)
    bad = np.abs(v[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1) > 1e-6
    if bad.any():
        raise SplatplanError(f"viewmats[{int(np.argmax(bad))}]: last row must be [0, 0, 0, 1] (a rigid world-to-camera transform)")
    r = v[:, :3, :3]
    err = np.abs(r @ np.transpose(r, (0, 2, 1)) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(r)
    bad = (err > 1e-3) | (det < 0.5)
    if bad.any():
        i = int(np.argmax(bad))
        raise SplatplanError(
            f"viewmats[{i}] is singular or not a rigid transform (rotation part: |R R^T - I| = {err[i]:.3g}, det = {det[i]:.3g}); "
            "pass world-to-camera matrices [[R, t], [0, 1]] with R a rotation"
        )
    fx, fy = k[:, 0, 0], k[:, 1, 1]
    bad = (fx <= 0) | (fy <= 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise SplatplanError(f"Ks[{i}] is singular: fx = {fx[i]:.4g} and fy = {fy[i]:.4g} must be > 0")
    off = np.stack([k[:, 0, 1], k[:, 1, 0], k[:, 2, 0], k[:, 2, 1], k[:, 2, 2] - 1.0], axis=1)
    bad = np.abs(off).max(axis=1) > 1e-6
    if bad.any():
        raise SplatplanError(f"Ks[{int(np.argmax(bad))}] must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)")
    return np.ascontiguousarray(v), np.ascontiguousarray(k)


def check_background(background) -> np.ndarray:
    bg = np.asarray(background, dtype=np.float64).reshape(-1)
    if bg.shape == (1,):
        bg = np.repeat(bg, 3)
    if bg.shape != (3,) or not np.all(np.isfinite(bg)):
        raise SplatplanError(f"background must be three finite numbers (R, G, B), got {background!r}")
    return bg


def check_planes(near: float, far: float) -> tuple[float, float]:
    near, far = float(near), float(far)
    if not (np.isfinite(near) and near > 0):
        raise SplatplanError(f"near must be a finite number > 0, got {near}")
    if not (far > near) or np.isnan(far):
        raise SplatplanError(f"far must be > near ({near}), got {far}")
    return near, min(far, 3.0e38)


def check_render_args(viewmats, Ks, width, height, near, far, background):
    """Validate the arguments every renderer's ``render`` takes.

    Returns (viewmats (B, 4, 4), Ks (B, 3, 3), width, height, near, far, background (3,)), see
    :func:`check_cameras`, :func:`check_image_size`, :func:`check_planes`, :func:`check_background`.
    """
    width, height = check_image_size(width, height)
    v, k = check_cameras(viewmats, Ks)
    near, far = check_planes(near, far)
    return v, k, width, height, near, far, check_background(background)


def estimate_bytes(b: int, width: int, height: int) -> int:
    """Bytes of the outputs of one call (rgb + depth + alpha, float32)."""
    return int(b) * int(width) * int(height) * 5 * 4


def camera_arrays(viewmats: np.ndarray, Ks: np.ndarray, width: int, height: int) -> dict[str, np.ndarray]:
    """Per-camera quantities every implementation uses (float64).

    Returns rot (B, 3, 3), trans (B, 3), campos (B, 3) camera centres (world), intr (B, 4)
    fx, fy, cx, cy, and lims (B, 4) the guard-band limits of x/z and y/z:
    (-lim_x_neg, lim_x_pos, -lim_y_neg, lim_y_pos) as (lx_neg, lx_pos, ly_neg, ly_pos).
    """
    rot = viewmats[:, :3, :3]
    trans = viewmats[:, :3, 3]
    campos = -np.einsum("bji,bj->bi", rot, trans)  # -R^T t
    fx, fy, cx, cy = Ks[:, 0, 0], Ks[:, 1, 1], Ks[:, 0, 2], Ks[:, 1, 2]
    tan_x = 0.5 * width / fx
    tan_y = 0.5 * height / fy
    lims = np.stack(
        [cx / fx + GUARD * tan_x, (width - cx) / fx + GUARD * tan_x, cy / fy + GUARD * tan_y, (height - cy) / fy + GUARD * tan_y],
        axis=1,
    )
    return {
        "rot": rot,
        "trans": trans,
        "campos": campos,
        "intr": np.stack([fx, fy, cx, cy], axis=1),
        "lims": lims,
    }
