"""Random scenes and cameras for the renderer tests."""

from __future__ import annotations

import numpy as np

from splatplan._warp import wp
from splatplan.render import intrinsics_from_fov, look_at
from splatplan.scenes.splats import Splats

DEVICES = ["cpu"] + (["cuda"] if wp().is_cuda_available() else [])


def random_scene(n: int = 200, sh_degree: int = 0, disks: float = 0.25, seed: int = 0) -> Splats:
    """Anisotropic splats in [-1, 1]^3 (a fraction of 2DGS disks), SH up to ``sh_degree``."""
    rng = np.random.default_rng(seed)
    means = rng.uniform(-1, 1, (n, 3))
    quats = rng.normal(size=(n, 4))
    scales = np.exp(rng.uniform(np.log(0.01), np.log(0.25), (n, 3)))
    scales[: int(disks * n), 2] = 0.0  # 2DGS disks
    opac = rng.uniform(0.02, 1.0, n)
    colors = rng.uniform(0, 1, (n, 3))
    k = (sh_degree + 1) ** 2 - 1
    sh = rng.normal(0, 0.25, (n, k, 3)) if k else None
    return Splats(means, quats, scales, opac, colors, sh)


def with_near_splats(scene: Splats, eye, target, seed: int = 1) -> Splats:
    """Add splats behind the camera at ``eye`` and straddling / just beyond its near plane."""
    rng = np.random.default_rng(seed)
    eye = np.asarray(eye, float)
    f = np.asarray(target, float) - eye
    f /= np.linalg.norm(f)
    side = np.cross(f, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    pts = [eye - 0.3 * f, eye - 0.005 * f, eye + 0.005 * f + 0.01 * side]  # behind, behind near, before near
    pts += [eye + d * f + o * side for d, o in ((0.012, 0.0), (0.03, 0.02), (0.06, -0.03), (0.2, 0.05))]  # straddling / close
    m = len(pts)
    extra = Splats(
        np.array(pts),
        rng.normal(size=(m, 4)),
        np.column_stack([np.full(m, 0.04), np.full(m, 0.02), np.full(m, 0.01)]),
        np.full(m, 0.6),
        rng.uniform(0, 1, (m, 3)),
        None if scene.sh_rest is None else rng.normal(0, 0.25, (m,) + scene.sh_rest.shape[1:]),
    )
    sh = None if scene.sh_rest is None else np.concatenate([scene.sh_rest, extra.sh_rest])
    return Splats(
        np.concatenate([scene.means, extra.means]), np.concatenate([scene.quats, extra.quats]),
        np.concatenate([scene.scales, extra.scales]), np.concatenate([scene.opacities, extra.opacities]),
        np.concatenate([scene.colors, extra.colors]), sh,
    )  # fmt: skip


#: (eye, target): outside looking in, outside from below, inside looking out, inside at a corner.
VIEWS = [
    ((3.0, 0.5, 1.0), (0.0, 0.0, 0.0)),
    ((-1.5, -2.0, -0.8), (0.1, 0.0, 0.2)),
    ((0.1, 0.2, 0.3), (1.0, -0.4, 0.1)),
    ((0.8, 0.8, 0.8), (-1.0, -1.0, -0.5)),
]


def cameras(width: int, height: int, fov: float = 70.0):
    eyes = np.array([v[0] for v in VIEWS])
    targets = np.array([v[1] for v in VIEWS])
    return look_at(eyes, targets), intrinsics_from_fov(fov, width, height)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)
