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
