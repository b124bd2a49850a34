"""Absurd splats: values a reader accepts (finite, unit quaternions, positive stds) that no trained
scene has, as a flipped byte or a wrong unit would make them. ``splatplan info`` prints them.

A load that "succeeds" on a corrupted file usually shows up here: one mean a million scene-sizes
away, a std larger than the whole scene, a std below float32's resolution of the coordinates.
"""

from __future__ import annotations

import numpy as np

__all__ = ["absurd_splats"]

#: a mean farther than this many robust scene extents from the robust centre is absurd
FAR_EXTENTS = 1e3
#: a largest std above this many robust extents is absurd
HUGE_STD_EXTENTS = 1e2
#: a coordinate magnitude above this (scene units) is beyond any capture (float32 keeps ~7 digits)
MAX_ABS_COORD = 1e7


def absurd_splats(splats) -> list[str]:
    """One line per kind of absurd splat found (empty for a sane scene).

    Robust frame: the 1st..99th percentile box of the means (extent = its largest side; outliers
    do not stretch it). Checks: means far outside it or beyond ``MAX_ABS_COORD``; stds larger than
    ``HUGE_STD_EXTENTS`` extents; stds that are all zero (a 3D splat with no volume).
    """
    n = len(splats)
    if n == 0:
        return ["the scene has no splats"]
    m = np.asarray(splats.means, np.float64)  # (N, 3) scene units
    s = np.asarray(splats.scales, np.float64)  # (N, 3) linear stds
    lo, hi = np.percentile(m, 1, axis=0), np.percentile(m, 99, axis=0)
    extent = max(float(np.max(hi - lo)), 1e-9)
    centre = 0.5 * (lo + hi)
    out = []
    dist = np.max(np.abs(m - centre), axis=1) / extent  # (N,) in robust extents
    far = dist > FAR_EXTENTS
    if far.any():
        out.append(f"{int(far.sum()):,} splat(s) more than {FAR_EXTENTS:g}x the scene's extent ({extent:.3g}) from its centre (farthest {dist.max():.3g}x)")
    big = np.abs(m).max(axis=1) > MAX_ABS_COORD
    if big.any():
        out.append(f"{int(big.sum()):,} splat(s) with a coordinate beyond {MAX_ABS_COORD:g} (largest {np.abs(m).max():.3g})")
    huge = s.max(axis=1) > HUGE_STD_EXTENTS * extent
    if huge.any():
        out.append(f"{int(huge.sum()):,} splat(s) with a std over {HUGE_STD_EXTENTS:g}x the scene's extent (largest {s.max():.3g})")
    flat = np.all(s <= 0, axis=1)
    if flat.any():
        out.append(f"{int(flat.sum()):,} splat(s) with every std 0 (no extent at all)")
    return out


#: the smallest non-zero std (scene units) the collision metric and the renderer take: its square
#: must stay a normal float32 (1e-30); smaller ones are rounding noise of a broken file
MIN_STD = 1e-15


def unusable_splats(splats) -> str | None:
    """Why the splats cannot be used for collision checks or rendering (None when they can): a
    coordinate or a std beyond :data:`MAX_ABS_COORD` (float32 grid and exp arithmetic overflows:
    ``info`` warns about these, the other commands refuse them in one line), or a non-zero std below
    :data:`MIN_STD`. The message says how many, the largest, and how to remove them."""
    if len(splats) == 0:
        return None
    m = np.abs(np.asarray(splats.means, np.float64))
    s = np.asarray(splats.scales, np.float64)
    far = m.max(axis=1) > MAX_ABS_COORD
    if far.any():
        return (f"{int(far.sum()):,} splat(s) with a coordinate beyond {MAX_ABS_COORD:g} (largest {m.max():.3g}); "
                "crop them away (splatplan scene align --crop ...) or fix the file")
    big = s.max(axis=1) > MAX_ABS_COORD
    if big.any():
        return f"{int(big.sum()):,} splat(s) with a std beyond {MAX_ABS_COORD:g} (largest {s.max():.3g}); fix the file"
    tiny = (s > 0) & (s < MIN_STD)
    if tiny.any():
        return f"{int(tiny.any(axis=1).sum()):,} splat(s) with a std below {MIN_STD:g} (smallest {s[tiny].min():.3g}) but not 0; fix the file"
    return None
