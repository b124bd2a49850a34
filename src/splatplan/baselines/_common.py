"""Shared plumbing of the baselines: scene tensors on a torch device, query conversion, chunking.

Every baseline reads the same splat arrays (see :mod:`splatplan.scenes.splats` for units and
frames): means (N, 3) in scene units, **wxyz** unit quaternions (N, 4) rotating the splat's local
frame into the world, linear standard deviations (N, 3) (third 0 for 2DGS disks), activated
opacities (N,). This module turns them into torch tensors once per scene so that repeated calls
do not redo the preprocessing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import torch

from .._arrays import array_kind, host_array
from .._warp import resolve_torch_device
from ..errors import SplatplanError

#: Default floor on the linear scales, in scene units, used where a formula divides by a scale
#: (Eberly's distance, SPLANNING's 1/s^2 and sqrt(det Sigma)). 2DGS disks have a zero third scale;
#: with the floor they become disks of thickness 2e-7 (1 sigma), geometrically irrelevant at the
#: scene scales we use (normalised to 1, robot radius 0.015) and far inside float32's range.
MIN_SCALE = 1e-7

#: Default cap on the number of elements of the largest intermediate (chunk x N x 3) tensor of the
#: dense batched baselines on CPU (2**22 float32 = 16 MiB). Chosen by measurement, not memory:
#: sweeping 2**18..2**26 (SPLANNING and ATLASNav, 50k splats x 1024 queries, 2 threads),
#: 2**20..2**22 was fastest and 2**26 was ~3x slower (page faults and cache misses on the huge
#: temporaries). On CUDA the cap is derived from the free device memory instead, so the dense
#: batch runs unchunked whenever it fits, like the originals (see :func:`elem_budget`).
CPU_ELEM_BUDGET = 1 << 22


def quat_to_rotmat_torch(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices from wxyz quaternions (normalised here).

    Args:
        q: wxyz quaternions, [..., 4].

    Returns:
        [..., 3, 3] rotation matrices mapping the local frame to the world frame.
    """
    q = q / q.norm(dim=-1, keepdim=True)
    w, x, y, z = q.unbind(-1)
    r = torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    )
    return r.reshape(q.shape[:-1] + (3, 3))


@dataclass
class SceneTensors:
    """The splat arrays every baseline needs, as torch tensors on one device.

    Attributes:
        means: [N, 3] splat centres, scene units.
        rotations: [N, 3, 3] local-to-world rotations R (columns = principal axes).
        scales: [N, 3] linear standard deviations along the local axes (unfloored).
        opacities: [N] activated opacities in [0, 1].
    """

    means: torch.Tensor
    rotations: torch.Tensor
    scales: torch.Tensor
    opacities: torch.Tensor

    def __len__(self) -> int:
        return int(self.means.shape[0])

    @property
    def device(self) -> torch.device:
        return self.means.device

    @property
    def dtype(self) -> torch.dtype:
        return self.means.dtype


def as_scene_tensors(
    splats_or_tensors: Any,
    device: str | torch.device = "auto",
    dtype: torch.dtype = torch.float32,
) -> SceneTensors:
    """Convert a scene to :class:`SceneTensors` on ``device``.

    Args:
        splats_or_tensors: a :class:`~splatplan.scenes.splats.Splats`, a :class:`SceneTensors`, or a
            mapping with keys ``means`` [N, 3], ``quats`` [N, 4] (wxyz), ``scales`` [N, 3] (linear
            std) and optionally ``opacities`` [N] (default 1); numpy arrays or torch tensors.
        device: "auto" (CUDA when present, else the CPU), "cpu", "cuda", "cuda:N" or a ``torch.device``.
        dtype: floating dtype of every tensor (the originals run in float32).

    Returns:
        The scene tensors (rotations precomputed from the quaternions).
    """
    device = resolve_torch_device(device)
    if isinstance(splats_or_tensors, SceneTensors):
        s = splats_or_tensors
        return SceneTensors(*(t.to(device=device, dtype=dtype) for t in (s.means, s.rotations, s.scales, s.opacities)))
    if isinstance(splats_or_tensors, Mapping):
        get = splats_or_tensors.get
        means, quats, scales, opac = get("means"), get("quats"), get("scales"), get("opacities")
    elif all(hasattr(splats_or_tensors, k) for k in ("means", "quats", "scales")):
        s = splats_or_tensors
        means, quats, scales, opac = s.means, s.quats, s.scales, getattr(s, "opacities", None)
    else:
        raise SplatplanError(
            f"baselines need a Splats object or a mapping with means/quats/scales[/opacities], got {type(splats_or_tensors).__name__}"
        )
    if means is None or quats is None or scales is None:
        raise SplatplanError("baselines need 'means', 'quats' (wxyz) and 'scales' (linear std) arrays")

    def _t(a: Any) -> torch.Tensor:
        # Quaternions are normalised in float64 before the cast, as in quat_to_rotmat.
        t = a if array_kind(a) == "torch" else torch.as_tensor(host_array(a))
        return t.to(device=device, dtype=torch.float64)

    means_t, quats_t, scales_t = _t(means), _t(quats), _t(scales)
    n = means_t.shape[0]
    if means_t.shape != (n, 3) or quats_t.shape != (n, 4) or scales_t.shape != (n, 3):
        raise SplatplanError(
            f"baseline scene arrays have shapes means {tuple(means_t.shape)}, quats {tuple(quats_t.shape)}, "
            f"scales {tuple(scales_t.shape)}; expected (N, 3), (N, 4), (N, 3)"
        )
    if n == 0:
        raise SplatplanError("the scene has no splats")
    opac_t = torch.ones(n, dtype=torch.float64, device=device) if opac is None else _t(opac).reshape(n)
    qn = quats_t.norm(dim=-1)
    if bool((qn < 1e-12).any()):
        raise SplatplanError(f"{int((qn < 1e-12).sum())} splat(s) have a zero quaternion; drop or fix them first")
    if not all(bool(torch.isfinite(t).all()) for t in (means_t, quats_t, scales_t, opac_t)):
        raise SplatplanError("the scene has NaN/Inf values; run Splats.validate() to find them")
    if bool((scales_t < 0).any()):
        raise SplatplanError("the scene has negative scales (are they log-scales? pass linear std)")
    rot = quat_to_rotmat_torch(quats_t)  # [N, 3, 3], in float64 then cast
    return SceneTensors(
        means=means_t.to(dtype), rotations=rot.to(dtype), scales=scales_t.to(dtype), opacities=opac_t.to(dtype)
    )


def as_centers(centers: Any, device: torch.device, dtype: torch.dtype) -> torch.Tensor:
    """Query sphere centres as a [B, 3] tensor (a single (3,) centre becomes [1, 3])."""
    c = centers if array_kind(centers) == "torch" else torch.as_tensor(np.asarray(host_array(centers), dtype=np.float64))
    c = c.to(device=device, dtype=dtype)
    if c.ndim == 1 and c.shape[0] == 3:
        c = c[None]
    if c.ndim != 2 or c.shape[1] != 3:
        raise SplatplanError(f"centers must have shape (B, 3), got {tuple(c.shape)}")
    return c


def check_radius(radius: float) -> float:
    """The robot sphere radius as a float; it must be positive and finite."""
    r = float(radius)
    if not np.isfinite(r) or r <= 0:
        raise SplatplanError(f"the robot sphere radius must be positive and finite, got {radius!r}")
    return r


def elem_budget(device: torch.device, dtype: torch.dtype, n_live: int, max_elems: int | None) -> int:
    """Largest element count allowed for one intermediate tensor of a dense batched baseline.

    Args:
        device: where the tensors live.
        dtype: their dtype.
        n_live: how many tensors of that size are alive at the peak (a rough count).
        max_elems: an explicit cap; wins when given.

    Returns:
        ``max_elems`` when given; on CUDA, 80% of the free memory split over ``n_live`` tensors;
        on CPU :data:`CPU_ELEM_BUDGET`.
    """
    if max_elems is not None:
        return max(1, int(max_elems))
    if device.type == "cuda":
        free, _ = torch.cuda.mem_get_info(device)
        return max(1, int(0.8 * free / (n_live * torch.finfo(dtype).bits // 8)))
    return CPU_ELEM_BUDGET


def to_numpy(x: torch.Tensor) -> np.ndarray:
    """A float64 numpy copy of a tensor (on any device)."""
    return x.detach().to("cpu", torch.float64).numpy()


def sync(device: torch.device) -> None:
    """Wait for queued device work (no-op on CPU); used by the timing helpers."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)


class Baseline:
    """What the four baseline classes share: the scene tensors on one torch device, queries in
    blocks of rows, the oriented score and the native decision.

    A subclass sets ``native_batch`` (queries per evaluation in the original code base),
    ``orientation`` (-1 when :meth:`collision_score` negates the native score, +1 when the native
    score already grows with collision) and ``threshold`` (the native decision boundary, see
    :meth:`decide`), and implements :meth:`score_torch` (the native score of a [b, 3] block of
    centres -> [b]).

    Args:
        splats_or_tensors: a Splats, SceneTensors or mapping of arrays (see :func:`as_scene_tensors`).
        device: "auto" (CUDA when present, else the CPU), "cpu", "cuda", "cuda:N" or a torch.device.
        dtype: torch dtype of the scene tensors (float32 as the originals).
    """

    native_batch: int = 1
    orientation: float = -1.0
    threshold: float = 0.0

    def __init__(self, splats_or_tensors: Any, device: str | torch.device, dtype: torch.dtype) -> None:
        self.scene: SceneTensors = as_scene_tensors(splats_or_tensors, device, dtype)

    @property
    def device(self) -> torch.device:
        return self.scene.device

    def rows(self, batch: int) -> int:
        """Queries per :meth:`score_torch` call for a caller's ``batch`` (a memory cap may lower it)."""
        return max(1, int(batch))

    def score_torch(self, centers: torch.Tensor, radius: float) -> torch.Tensor:  # [b, 3] -> [b]
        raise NotImplementedError

    @classmethod
    def decide(cls, score: np.ndarray, threshold: float | None = None) -> np.ndarray:
        """The method's own decision from its native scores, bool (B,): collision iff the native
        score is below ``threshold`` (default the class's) when ``orientation`` is -1, above it when
        +1; i.e. iff :meth:`collision_score` is above :meth:`collision_threshold`."""
        score, t = np.asarray(score), cls.threshold if threshold is None else threshold
        return score < t if cls.orientation < 0 else score > t

    @classmethod
    def collision_threshold(cls) -> float:
        """The value of :meth:`collision_score` at the native decision boundary (collision iff above)."""
        return cls.orientation * cls.threshold

    @torch.no_grad()
    def score(self, centers: Any, radius: float, batch: int | None = None) -> np.ndarray:
        """Native score per centre, float64 (B,).

        Args:
            centers: (B, 3) sphere centres, scene units.
            radius: sphere radius r > 0, scene units.
            batch: queries evaluated together (None: ``native_batch``; any value gives the same
                scores, larger ones faster).
        """
        c = as_centers(centers, self.device, self.scene.dtype)
        step = self.rows(self.native_batch if batch is None else batch)
        out = [self.score_torch(c[i : i + step], radius) for i in range(0, c.shape[0], step)]
        return to_numpy(torch.cat(out)) if out else np.zeros(0)

    def collision_score(self, centers: Any, radius: float, batch: int | None = None) -> np.ndarray:
        """The native score oriented so that larger = more likely in collision, float64 (B,)."""
        return self.orientation * self.score(centers, radius, batch)

    def in_collision(self, centers: Any, radius: float, batch: int | None = None) -> np.ndarray:
        """The method's own classifier: bool (B,)."""
        return self.decide(self.score(centers, radius, batch))

    @classmethod
    def evaluate(cls, splats_or_tensors: Any, centers: Any, radius: float, device: str | torch.device = "auto", oriented: bool = False, **method_kw) -> np.ndarray:
        """One-off scores: ``cls(splats_or_tensors, device, **method_kw)`` then :meth:`score`
        (:meth:`collision_score` when ``oriented``); ``method_kw`` may carry ``batch``."""
        batch = method_kw.pop("batch", None)
        obj = cls(splats_or_tensors, device, **method_kw)
        return obj.collision_score(centers, radius, batch) if oriented else obj.score(centers, radius, batch)
