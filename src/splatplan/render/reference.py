"""Slow, obviously-correct numpy reference of the splat renderer (float64, no tiles).

Every splat is tested against every pixel; the maths is that of :mod:`.wp_raster` (see
:mod:`.config` for the conventions and constants). The kernels' tile binning drops nothing the
reference draws: a splat's opacity-aware bounding box contains every pixel where its alpha
reaches ``ALPHA_MIN`` (see ``wp_raster.project_kernel``), so the two differ only by float32
rounding. Use for tests on small scenes and images only.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypedDict

import numpy as np

from ..scenes.splats import Splats, quat_to_rotmat
from .config import (
    ALPHA_MAX, ALPHA_MIN, LOW_PASS, SH_C1, SH_C2, SH_C3, T_MIN, RenderResult, camera_arrays,
    check_render_args, resolve_sh_degree, scene_sh_degree, thickened_scales,
)  # fmt: skip

__all__ = ["scene_arrays", "eval_sh", "project_reference", "render_reference"]


class SceneArrays(TypedDict):
    """What :func:`scene_arrays` returns (float64 arrays, world frame)."""

    means: np.ndarray  # (N, 3)
    covs: np.ndarray  # (N, 3, 3)
    opacities: np.ndarray  # (N,)
    colors: np.ndarray  # (N, 3)
    sh: np.ndarray  # (N, K, 3)
    degree: int


def scene_arrays(scene: Splats) -> SceneArrays:
    """The per-splat data every renderer uses (float64, world frame).

    Returns means (N, 3), covs (N, 3, 3) = R diag(s^2) R^T with 2DGS disks (third std 0) given the
    third std ``DISK_THICKNESS`` x their larger std, opacities (N,), colors (N, 3) (SH band 0
    already + 0.5, i.e. ``Splats.colors``), sh (N, K, 3) higher bands (K may be 0) and
    ``degree`` the scene's SH degree.
    """
    scales = thickened_scales(scene.scales)  # (N, 3) linear std
    rot = quat_to_rotmat(scene.quats) if len(scene) else np.zeros((0, 3, 3))  # (N, 3, 3) local -> world
    covs = np.einsum("nij,nj,nkj->nik", rot, scales**2, rot)
    sh = scene.sh_rest if scene.sh_rest is not None else np.zeros((len(scene), 0, 3), np.float32)
    degree = scene_sh_degree(scene.sh_rest)
    return {
        "means": scene.means.astype(np.float64),
        "covs": covs,
        "opacities": scene.opacities.astype(np.float64),
        "colors": scene.colors.astype(np.float64),
        "sh": sh[:, : (degree + 1) ** 2 - 1].astype(np.float64),
        "degree": degree,
    }


def eval_sh(colors: np.ndarray, sh: np.ndarray, dirs: np.ndarray, degree: int) -> np.ndarray:
    """Colour at unit viewing directions: colors (N, 3) (band 0 + 0.5), sh (N, K, 3), dirs (N, 3).

    Real SH basis and sign conventions of the INRIA code (``sh[:, k]`` = coefficient k + 1).
    Returns (N, 3) clamped at 0.
    """
    c = colors.astype(np.float64).copy()
    if degree >= 1:
        x, y, z = dirs[:, 0:1], dirs[:, 1:2], dirs[:, 2:3]
        c += SH_C1 * (-y * sh[:, 0] + z * sh[:, 1] - x * sh[:, 2])
        if degree >= 2:
            xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
            c += (
                SH_C2[0] * xy * sh[:, 3] + SH_C2[1] * yz * sh[:, 4] + SH_C2[2] * (2 * zz - xx - yy) * sh[:, 5]
                + SH_C2[3] * xz * sh[:, 6] + SH_C2[4] * (xx - yy) * sh[:, 7]
            )  # fmt: skip
            if degree >= 3:
                c += (
                    SH_C3[0] * y * (3 * xx - yy) * sh[:, 8] + SH_C3[1] * xy * z * sh[:, 9]
                    + SH_C3[2] * y * (4 * zz - xx - yy) * sh[:, 10] + SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy) * sh[:, 11]
                    + SH_C3[4] * x * (4 * zz - xx - yy) * sh[:, 12] + SH_C3[5] * z * (xx - yy) * sh[:, 13]
                    + SH_C3[6] * x * (xx - 3 * yy) * sh[:, 14]
                )  # fmt: skip
    return np.maximum(c, 0.0)


def project_reference(arrs: Mapping[str, Any], cam: dict, b: int, width: int, height: int, near: float, far: float, degree: int) -> dict[str, np.ndarray]:
    """Project every splat into camera b. Returns per-splat arrays and a ``valid`` mask (N,).

    ``valid`` drops splats whose mean lies outside [near, far] along the view axis and those with
    opacity below ``ALPHA_MIN`` (they can never contribute); nothing is culled by the image
    bounds here (the reference tests every pixel).
    """
    rot, t = cam["rot"][b], cam["trans"][b]
    fx, fy, cx, cy = cam["intr"][b]
    lxn, lxp, lyn, lyp = cam["lims"][b]
    p = arrs["means"] @ rot.T + t  # (N, 3) camera frame
    z = p[:, 2]
    valid = (z >= near) & (z <= far) & (arrs["opacities"] >= ALPHA_MIN)
    zs = np.where(valid, z, 1.0)
    tx = np.clip(p[:, 0] / zs, -lxn, lxp) * zs  # guard band: clamp only inside the Jacobian
    ty = np.clip(p[:, 1] / zs, -lyn, lyp) * zs
    n = len(z)
    jac = np.zeros((n, 2, 3))
    jac[:, 0, 0] = fx / zs
    jac[:, 0, 2] = -fx * tx / zs**2
    jac[:, 1, 1] = fy / zs
    jac[:, 1, 2] = -fy * ty / zs**2
    cov_c = rot @ arrs["covs"] @ rot.T  # (N, 3, 3) camera frame
    cov2 = jac @ cov_c @ np.transpose(jac, (0, 2, 1)) + LOW_PASS * np.eye(2)  # (N, 2, 2) px^2
    a, bb, c = cov2[:, 0, 0], cov2[:, 0, 1], cov2[:, 1, 1]
    det = a * c - bb * bb
    valid &= (det > 0) & np.isfinite(det)
    det = np.where(valid, det, 1.0)
    conic = np.stack([c / det, -bb / det, a / det], axis=1)  # (N, 3) inverse 2D covariance (xx, xy, yy)
    xy = np.stack([fx * p[:, 0] / zs + cx, fy * p[:, 1] / zs + cy], axis=1)  # (N, 2) pixels
    dirs = arrs["means"] - cam["campos"][b]
    dirs = dirs / np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-30)
    rgb = eval_sh(arrs["colors"], arrs["sh"], dirs, degree)
    return {"xy": xy, "conic": conic, "depth": z, "rgb": rgb, "opacity": arrs["opacities"], "valid": valid}


def blend_reference(pr: dict, width: int, height: int, background: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Front-to-back blending of the valid projected splats over all pixels. Returns rgb (H, W, 3), depth, alpha (H, W)."""
    idx = np.flatnonzero(pr["valid"])
    idx = idx[np.argsort(pr["depth"][idx], kind="stable")]  # front to back by view depth of the mean
    px = np.stack(np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5), axis=-1).reshape(-1, 2)  # (P, 2) centres
    p = px.shape[0]
    trans = np.ones(p)
    done = np.zeros(p, dtype=bool)
    rgb = np.zeros((p, 3))
    dacc = np.zeros(p)
    for i in idx:
        d = px - pr["xy"][i]
        ca, cb, cc = pr["conic"][i]
        power = -0.5 * (ca * d[:, 0] ** 2 + cc * d[:, 1] ** 2) - cb * d[:, 0] * d[:, 1]
        alpha = np.minimum(ALPHA_MAX, pr["opacity"][i] * np.exp(np.minimum(power, 0.0)))
        hit = (alpha >= ALPHA_MIN) & (power <= 0) & ~done
        next_t = trans * (1.0 - alpha)
        stop = hit & (next_t < T_MIN)
        done |= stop
        add = hit & ~stop
        w = np.where(add, alpha * trans, 0.0)
        rgb += w[:, None] * pr["rgb"][i]
        dacc += w * pr["depth"][i]
        trans = np.where(add, next_t, trans)
    alpha_img = 1.0 - trans
    depth = np.where(alpha_img > 0, dacc / np.where(alpha_img > 0, alpha_img, 1.0), 0.0)
    rgb += trans[:, None] * background
    return rgb.reshape(height, width, 3), depth.reshape(height, width), alpha_img.reshape(height, width)


def render_reference(
    scene: Splats, viewmats, Ks, width: int, height: int, *, near: float = 0.01, far: float = 1e10, background=(0.0, 0.0, 0.0), sh_degree: int | None = None
) -> RenderResult:
    """Numpy reference of :func:`splatplan.render` (same arguments and conventions; CPU, slow)."""
    v, k, width, height, near, far, bg = check_render_args(viewmats, Ks, width, height, near, far, background)
    arrs = scene_arrays(scene)
    degree = resolve_sh_degree(sh_degree, int(arrs["degree"]))
    cam = camera_arrays(v, k, width, height)
    b = v.shape[0]
    rgb = np.zeros((b, height, width, 3), np.float32)
    depth = np.zeros((b, height, width), np.float32)
    alpha = np.zeros((b, height, width), np.float32)
    for i in range(b):
        pr = project_reference(arrs, cam, i, width, height, near, far, degree)
        rgb[i], depth[i], alpha[i] = blend_reference(pr, width, height, bg)
    return RenderResult(rgb=rgb, depth=depth, alpha=alpha)
