"""Floater filter: drop splats that are both nearly transparent and unusually large.

Trained scenes carry "floaters": big, faint splats in free space that barely show in renders but
would block a collision checker. The paper discards splats that are **both** low-opacity and
large; the default rule (SPEC section 1) drops splat i when

    o_i < opacity_below   and   max(s_i) > scale_factor * median_j(max(s_j))

with ``s`` the linear standard deviations. A faint small splat or an opaque large one is kept.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from ..errors import SplatplanError
from .splats import Splats


@dataclass(frozen=True)
class FilterReport:
    """What :func:`filter_floaters` did."""

    n_in: int  #: splats before filtering
    n_dropped: int  #: splats removed as floaters
    n_out: int  #: splats kept
    opacity_below: float  #: opacity threshold (drop only if o < this)
    scale_factor: float  #: size threshold as a multiple of the median largest std
    median_max_scale: float  #: median over the scene of each splat's largest std (scene units)
    max_scale_above: float  #: absolute size threshold, scale_factor * median_max_scale (scene units)

    def as_dict(self) -> dict:
        """Plain-dict form (stored in ``Splats.info["floaters"]``)."""
        return asdict(self)


def floater_mask(
    opacities: np.ndarray,  # (N,) activated opacity
    scales: np.ndarray,  # (N, 3) linear std
    opacity_below: float = 0.1,
    scale_factor: float = 5.0,
) -> tuple[np.ndarray, float]:
    """Boolean (N,) mask of floaters and the median largest std it was measured against."""
    max_s = np.max(scales, axis=1)  # (N,)
    median = float(np.median(max_s)) if max_s.size else 0.0
    return (opacities < opacity_below) & (max_s > scale_factor * median), median


def filter_floaters(splats: Splats, opacity_below: float = 0.1, scale_factor: float = 5.0) -> tuple[Splats, FilterReport]:
    """Drop low-opacity, large splats (see the module docstring for the rule).

    Args:
        splats: the scene.
        opacity_below: opacity threshold in [0, 1]; 0 disables the filter.
        scale_factor: size threshold relative to the median largest std; must be > 0.

    Returns:
        (kept splats, report). The input is not modified; ``info`` is copied. When nothing is
        dropped the result shares the input's arrays (no copy).

    Raises:
        SplatplanError: a threshold is out of range.
    """
    if not 0.0 <= opacity_below <= 1.0:
        raise SplatplanError(f"floater opacity threshold must lie in [0, 1], got {opacity_below}")
    if not scale_factor > 0.0:
        raise SplatplanError(f"floater scale factor must be > 0, got {scale_factor}")
    drop, median = floater_mask(splats.opacities, splats.scales, opacity_below, scale_factor)
    n_dropped = int(drop.sum())
    report = FilterReport(
        n_in=len(splats),
        n_dropped=n_dropped,
        n_out=len(splats) - n_dropped,
        opacity_below=float(opacity_below),
        scale_factor=float(scale_factor),
        median_max_scale=median,
        max_scale_above=scale_factor * median,
    )
    if n_dropped == 0:  # nothing to drop: share the arrays instead of copying them
        return replace(splats, info=dict(splats.info)), report
    return splats.subset(~drop), report


def isolated_mask(
    means: np.ndarray,  # (N, 3) scene units
    opacities: np.ndarray,  # (N,) activated opacity
    k: int = 8,
    factor: float = 3.0,
    opacity_below: float = 0.3,
    candidates: np.ndarray | None = None,  # (N,) bool: the splats tested and counted as neighbours
) -> np.ndarray:
    """(N,) bool: faint splats floating alone in free space (a statistical outlier rule, as in
    point-cloud cleaning): opacity below ``opacity_below`` **and** a mean distance to the ``k``
    nearest other means above ``factor`` times the scene's median of that distance.

    Real captures carry such floaters in the middle of rooms (opacity 0.01-0.3, stds 2-5x the
    median, so the size rule of :func:`floater_mask` misses them) and a robot's body meets some of
    them wherever it stands. Surfaces are dense (small k-NN distances) and opaque splats are never
    dropped, so walls, furniture and thin objects stay. ``candidates`` restricts both the tested
    splats and their neighbours (e.g. everything but the floor: a floater 20 cm above a dense floor
    is still a floater); the others are never dropped.
    """
    from scipy.spatial import cKDTree

    m = np.asarray(means, np.float64)
    idx = np.arange(len(m)) if candidates is None else np.flatnonzero(candidates)
    out = np.zeros(len(m), bool)
    if len(idx) <= k:
        return out
    d, _ = cKDTree(m[idx]).query(m[idx], k=k + 1)
    dk = d[:, 1:].mean(axis=1)
    out[idx] = (np.asarray(opacities)[idx] < opacity_below) & (dk > factor * float(np.median(dk)))
    return out


def far_shell_mask(
    means: np.ndarray,  # (N, 3) scene units
    gap: float = 2.0,
    far: float = 4.0,
) -> np.ndarray:
    """(N,) bool: a background shell and far floaters: the splats beyond the first wide empty gap
    in their distances from the scene's centre (the per-axis median of the means).

    Sorted by distance r, the cut is the first pair of neighbours with ``r[i+1] >= gap * r[i]``
    (nothing between r and ``gap`` r: an empty spherical band) that lies beyond the median
    distance and starts at ``r[i+1] >= far`` times it; everything past the cut is the shell. A
    240 m sky sphere around a 1 m capture, or a few splats 50 m out, are cut; a room's walls and
    the open ground of an outdoor capture (distances without such a gap) are not. Size and
    opacity play no part, so a shell of small opaque splats is found too. Assumes the shell holds
    fewer splats than the scene (the median is the scene's).
    """
    m = np.asarray(means, np.float64)
    out = np.zeros(len(m), bool)
    if len(m) < 4:
        return out
    r = np.linalg.norm(m - np.median(m, axis=0), axis=1)
    rs = np.sort(r)
    r_med = float(rs[len(rs) // 2])
    ratio = rs[1:] / np.maximum(rs[:-1], 1e-30)
    ok = (ratio >= gap) & (rs[1:] >= far * r_med) & (np.arange(len(rs) - 1) >= len(rs) // 2)
    if ok.any():
        out = r > rs[int(np.argmax(ok))]
    return out
