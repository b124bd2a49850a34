"""Splat levels of the built-in scenes: the look of the splats at a Gaussian-size level and how
many there are.

* :func:`level_config` - the :class:`~splatplan.scenes.builtin.surface_splats.SurfaceSplatConfig` of a
  level 1..5 (level 1: the statistics of real captures; higher: larger, thicker, noisier splats).
  Stonehenge has all five levels; the box-built scenes (tabletop, apartment) use level 1.
* :func:`default_n_splats` - Stonehenge's splat count at a level (``200k / 1.8**(L-1)``).
* :func:`splat_count` - a caller's splat count (or a scene's default) checked.

A leaf of the built-in scenes: it imports only the surface sampler's configuration type.
"""

from __future__ import annotations

from ...errors import SplatplanError
from .surface_splats import SurfaceSplatConfig

__all__ = ["LEVELS", "LEVEL_RATIO", "N_SPLATS_LEVEL1", "default_n_splats", "level_config", "splat_count"]

#: The Gaussian-size levels.
LEVELS = (1, 2, 3, 4, 5)
#: Splat count at level 1 (the paper's Stonehenge has ~200k splats).
N_SPLATS_LEVEL1 = 200_000
#: Splat count ratio between consecutive levels.
LEVEL_RATIO = 1.8


def level_config(level: int) -> SurfaceSplatConfig:
    """Splat look for a Gaussian-size level 1..5 (higher: thicker, more anisotropic, noisier).

    The splat *size* follows from the count (spacing ~ 1/sqrt(n)). Level 1 is calibrated to the
    statistics of real trained captures (the truck, bathroom and banana scans in shared/data):
    log-std of the largest std ~0.8 with a heavy tail (p99 ~ 7x the median), needle-like in-plane
    shapes (median middle/largest std ~ 0.3) and normals a few degrees off the surface. Higher
    levels have larger splats (fewer of them over the same surfaces) with the same shape
    statistics, slightly thicker and with normals tilted more.
    """
    if level not in LEVELS:
        raise SplatplanError(f"stonehenge level must be 1..5, got {level}")
    k = level - 1
    return SurfaceSplatConfig(
        thickness=0.15 + 0.06 * k,
        anisotropy=0.6,
        size_jitter=0.5,
        normal_noise=0.15 + 0.02 * k,
        tangential_noise=0.2,
        tilt_deg=6.0 + 2.0 * k,
    )


def default_n_splats(level: int) -> int:
    """``round(200_000 / 1.8 ** (level - 1))``."""
    return int(round(N_SPLATS_LEVEL1 / LEVEL_RATIO ** (level - 1)))


def splat_count(n_splats: int | None, default: int) -> int:
    """``n_splats`` (``default`` when None) as an int >= 1."""
    n = default if n_splats is None else int(n_splats)
    if n < 1:
        raise SplatplanError(f"n_splats must be >= 1, got {n_splats}")
    return n
