"""The :class:`Splats` container: one Gaussian-splat scene in memory.

Units and frames
----------------
* ``means`` are in *scene units* (metres for metric captures, normalised units for the built-in
  scenes), in the scene's own world frame. Loaders keep the file's frame (INRIA captures are
  usually y-down); see :mod:`splatplan.scenes.transforms` for ``y_down_to_z_up``.
* ``quats`` are unit quaternions in **wxyz** order, rotating the splat's local frame into the world.
* ``scales`` are *linear* standard deviations along the splat's local axes (not log-scales). A 2DGS
  disk has ``scales[:, 2] == 0``.
* ``opacities`` are activated opacities in [0, 1] (not logits).
* ``colors`` are RGB from the SH DC term (0.5 + C0 * f_dc), nominally in [0, 1]; trained scenes
  may slightly exceed it (kept unclipped so files round-trip exactly).
* ``sh_rest`` optionally holds the higher SH coefficients, shape (N, K, 3), K in {3, 8, 15, 24}
  (SH degree 1..4), coefficient-major with the channel last.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import SplatplanError

SH_C0 = 0.28209479177387814


def quat_to_rotmat(q: np.ndarray) -> np.ndarray:
    """Rotation matrices from unit quaternions.

    Args:
        q: wxyz quaternions, shape (..., 4). Need not be normalised.

    Returns:
        Rotation matrices, shape (..., 3, 3), mapping local to world coordinates.
    """
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    r = np.empty(q.shape[:-1] + (3, 3), dtype=np.float64)
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - w * z)
    r[..., 0, 2] = 2 * (x * z + w * y)
    r[..., 1, 0] = 2 * (x * y + w * z)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - w * x)
    r[..., 2, 0] = 2 * (x * z - w * y)
    r[..., 2, 1] = 2 * (y * z + w * x)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of wxyz quaternions, shapes broadcast over (..., 4)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def rotmat_to_quat(r: np.ndarray) -> np.ndarray:
    """Unit wxyz quaternions (w >= 0) from rotation matrices of shape (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    r = np.asarray(r, dtype=np.float64)
    xyzw = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_quat()
    wxyz = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    wxyz *= np.where(wxyz[:, :1] < 0, -1.0, 1.0)
    return wxyz.reshape(r.shape[:-2] + (4,))


@dataclass
class Splats:
    """N Gaussian splats (see the module docstring for units and frames).

    Attributes:
        means: float32 (N, 3) centres.
        quats: float32 (N, 4) unit wxyz quaternions.
        scales: float32 (N, 3) linear standard deviations (>= 0; third is 0 for 2DGS disks).
        opacities: float32 (N,) activated opacity in [0, 1].
        colors: float32 (N, 3) RGB (SH band 0), nominally in [0, 1].
        sh_rest: optional float32 (N, K, 3) higher-order SH coefficients.
        source_format: short name of the format it was read from ("inria", "2dgs", ...).
        info: free-form metadata (e.g. counts dropped by filters).
    """

    means: np.ndarray
    quats: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    colors: np.ndarray
    sh_rest: np.ndarray | None = None
    source_format: str = "memory"
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        # no copy for contiguous float32 input; values beyond float32 become Inf without a
        # RuntimeWarning (validate() and the readers report them as NaN/Inf)
        with np.errstate(over="ignore", invalid="ignore"):
            self.means = np.ascontiguousarray(self.means, dtype=np.float32)
            self.quats = np.ascontiguousarray(self.quats, dtype=np.float32)
            self.scales = np.ascontiguousarray(self.scales, dtype=np.float32)
            self.opacities = np.ascontiguousarray(self.opacities, dtype=np.float32).reshape(-1)
            self.colors = np.ascontiguousarray(self.colors, dtype=np.float32)
            if self.sh_rest is not None:
                self.sh_rest = np.ascontiguousarray(self.sh_rest, dtype=np.float32)
        n = self.means.shape[0] if self.means.ndim == 2 else -1
        shapes = {
            "means": (self.means.shape, (n, 3)),
            "quats": (self.quats.shape, (n, 4)),
            "scales": (self.scales.shape, (n, 3)),
            "opacities": (self.opacities.shape, (n,)),
            "colors": (self.colors.shape, (n, 3)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise SplatplanError(f"Splats.{name} has shape {got}, expected {want}")
        if self.sh_rest is not None and (self.sh_rest.ndim != 3 or self.sh_rest.shape[0] != n or self.sh_rest.shape[2] != 3):
            raise SplatplanError(f"Splats.sh_rest has shape {self.sh_rest.shape}, expected ({n}, K, 3)")

    # ------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return int(self.means.shape[0])

    @property
    def is_2d(self) -> bool:
        """True when every splat is a flat disk (2DGS)."""
        return len(self) > 0 and bool(np.all(self.scales[:, 2] == 0))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the means, each float64 (3,)."""
        if len(self) == 0:
            raise SplatplanError("the scene has no splats")
        return self.means.min(0).astype(np.float64), self.means.max(0).astype(np.float64)

    def rotations(self) -> np.ndarray:
        """float64 (N, 3, 3) local-to-world rotation matrices."""
        return quat_to_rotmat(self.quats)

    def covariances(self) -> np.ndarray:
        """float64 (N, 3, 3) covariances R diag(s^2) R^T."""
        r = self.rotations()
        s2 = self.scales.astype(np.float64) ** 2
        return np.einsum("nij,nj,nkj->nik", r, s2, r)

    def subset(self, idx: np.ndarray) -> "Splats":
        """A new Splats with the rows selected by a boolean mask or an index array."""
        return replace(
            self,
            means=self.means[idx],
            quats=self.quats[idx],
            scales=self.scales[idx],
            opacities=self.opacities[idx],
            colors=self.colors[idx],
            sh_rest=None if self.sh_rest is None else self.sh_rest[idx],
            info=dict(self.info),
        )

    def validate(self, *, what: str = "scene") -> "Splats":
        """Raise :class:`SplatplanError` naming the first bad field (NaN/Inf, zero quats, bad scales).

        Returns self so calls chain.
        """
        for name in ("means", "quats", "scales", "opacities", "colors"):
            arr = getattr(self, name)
            bad = ~np.isfinite(arr)
            if bad.any():
                row = int(np.argwhere(bad)[0][0])
                raise SplatplanError(f"{what}: {int(bad.any(axis=tuple(range(1, arr.ndim))).sum()) if arr.ndim > 1 else int(bad.sum())} splat(s) have NaN/Inf in '{name}' (first at index {row})")
        with np.errstate(over="ignore"):
            qn = np.linalg.norm(self.quats.astype(np.float64), axis=1)
        if np.any(qn < 1e-8):
            raise SplatplanError(f"{what}: {int((qn < 1e-8).sum())} splat(s) have a zero quaternion (first at index {int(np.argmax(qn < 1e-8))})")
        if np.any(self.scales < 0):
            raise SplatplanError(f"{what}: {int((self.scales < 0).any(1).sum())} splat(s) have negative scales")
        if np.any(self.scales[:, :2] <= 0):
            raise SplatplanError(f"{what}: {int((self.scales[:, :2] <= 0).any(1).sum())} splat(s) have non-positive scales")
        if np.any((self.opacities < 0) | (self.opacities > 1)):
            raise SplatplanError(f"{what}: opacities must lie in [0, 1]")
        return self

    def normalized(self) -> "Splats":
        """Copy with unit quaternions (w >= 0)."""
        q = self.quats / np.linalg.norm(self.quats, axis=1, keepdims=True)
        q = q * np.where(q[:, :1] < 0, -1.0, 1.0).astype(np.float32)
        return replace(self, quats=q, info=dict(self.info))
