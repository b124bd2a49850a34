"""PlayCanvas / SuperSplat compressed ``.ply`` reader.

Layout (all fields read by name):

* ``chunk`` element, one row per 256 consecutive splats: ``min_x..max_z`` (position bounds),
  ``min_scale_x..max_scale_z`` (bounds of the **log** scales) and optionally
  ``min_r..max_b`` (colour bounds; absent in older files, where colours span [0, 1]).
* ``vertex`` element of packed ``uint32``, most significant bits first:

  - ``packed_position``: x 11 bits (bits 31..21), y 10 bits (20..11), z 11 bits (10..0), each an
    unsigned fraction v / (2^bits - 1) lerped between the chunk's min and max.
  - ``packed_scale``: the same 11/10/11 layout over the chunk's log-scale bounds, then exp.
  - ``packed_rotation``: bits 31..30 index (0..3) of the largest-magnitude quaternion component,
    then three 10-bit fields (29..20, 19..10, 9..0) holding the other three components in order,
    each u / 1023 in [0, 1] mapped to ``(u / 1023 - 0.5) * sqrt(2)`` in [-1/sqrt2, 1/sqrt2];
    the largest is ``sqrt(1 - a^2 - b^2 - c^2)`` (the encoder flips the sign so it is >= 0).
    Component order is ``rot_0..rot_3`` of the source INRIA file, i.e. **wxyz** (index 0 = w);
    verified on a real SuperSplat file by checking that each splat's thinnest axis follows the
    local surface normal of its neighbours (see ``tests/scenes/test_io_real_files.py``).
  - ``packed_color``: RGBA 8 bits each (R in bits 31..24). RGB is the colour 0.5 + C0 * f_dc,
    lerped over the chunk colour bounds when present; A is the activated opacity.

* optional ``sh`` element of ``uchar`` ``f_rest_*`` (INRIA channel-major order), each decoded as
  ``(u / 255 - 0.5) * 8`` (the inverse of the encoder's ``round((sh / 8 + 0.5) * 255)``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import plyfile

from .io_common import build_splats, exp_std, f_rest_layout, fill_sh_rest, scene_error
from .splats import Splats

#: Splats per chunk.
CHUNK_SIZE = 256

_CHUNK_REQUIRED = [f"{m}_{a}" for m in ("min", "max") for a in "xyz"] + [f"{m}_scale_{a}" for m in ("min", "max") for a in "xyz"]
_CHUNK_COLOR = [f"{m}_{c}" for m in ("min", "max") for c in "rgb"]
_VERTEX_REQUIRED = ["packed_position", "packed_rotation", "packed_scale", "packed_color"]


def unpack_unorm(packed: np.ndarray, shift: int, bits: int) -> np.ndarray:
    """float64 fraction in [0, 1] from ``bits`` bits of ``packed`` starting at bit ``shift``."""
    mask = (1 << bits) - 1
    return ((packed >> np.uint32(shift)) & np.uint32(mask)).astype(np.float64) / mask


def unpack_111011(packed: np.ndarray) -> np.ndarray:
    """(N, 3) fractions from uint32 packed as x 11 bits (high), y 10 bits, z 11 bits (low)."""
    return np.stack([unpack_unorm(packed, 21, 11), unpack_unorm(packed, 11, 10), unpack_unorm(packed, 0, 11)], axis=1)


def unpack_rotation(packed: np.ndarray) -> np.ndarray:
    """(N, 4) wxyz unit quaternions from the 2+10+10+10-bit smallest-three encoding."""
    packed = np.asarray(packed, dtype=np.uint32)
    small = np.stack([(unpack_unorm(packed, s, 10) - 0.5) * np.sqrt(2.0) for s in (20, 10, 0)], axis=1)  # (N, 3)
    largest = (packed >> np.uint32(30)).astype(np.int64)  # (N,) index in wxyz order
    m = np.sqrt(np.maximum(0.0, 1.0 - np.sum(small**2, axis=1)))  # (N,)
    q = np.empty((packed.shape[0], 4), dtype=np.float64)
    rows = np.arange(packed.shape[0])
    q[rows, largest] = m
    # the three stored components fill the other slots in increasing index order
    others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]  # (N, 3)
    q[rows[:, None], others] = small
    return q


def _lerp(lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    return lo + (hi - lo) * t


def decode_compressed_ply(ply: plyfile.PlyData, path: str | Path, *, drop_invalid: bool = False) -> Splats:
    """Decode a parsed compressed PLY (see the module docstring).

    Raises:
        SceneFormatError: missing elements or fields (named), too few chunks, a malformed ``sh``
            element, or bad decoded values.
    """
    names = {el.name for el in ply.elements}
    if not {"chunk", "vertex"} <= names:
        raise scene_error(path, f"compressed PLY needs 'chunk' and 'vertex' elements; found {sorted(names)}")
    chunk, vert = ply["chunk"].data, ply["vertex"].data
    for what, arr, required in (("chunk", chunk, _CHUNK_REQUIRED), ("vertex", vert, _VERTEX_REQUIRED)):
        missing = [f for f in required if f not in (arr.dtype.names or ())]
        if missing:
            raise scene_error(path, f"compressed PLY '{what}' element lacks field(s) {', '.join(missing)}")
    n = len(vert)
    n_chunks = -(-n // CHUNK_SIZE)
    if len(chunk) < n_chunks:
        raise scene_error(path, f"compressed PLY has {len(chunk)} chunk rows but {n} splats need {n_chunks} (one per {CHUNK_SIZE})")
    ci = np.arange(n) // CHUNK_SIZE  # (N,) chunk of each splat

    def bounds(prefix: str, axes: str) -> tuple[np.ndarray, np.ndarray]:  # ((N, 3), (N, 3))
        lo = np.stack([np.asarray(chunk[f"min_{prefix}{a}"], dtype=np.float64) for a in axes], axis=1)[ci]
        hi = np.stack([np.asarray(chunk[f"max_{prefix}{a}"], dtype=np.float64) for a in axes], axis=1)[ci]
        return lo, hi

    # Inf/NaN chunk bounds give Inf/NaN values here silently; build_splats reports them
    with np.errstate(over="ignore", invalid="ignore"):
        means = _lerp(*bounds("", "xyz"), unpack_111011(np.asarray(vert["packed_position"], dtype=np.uint32)))  # (N, 3)
        scales = exp_std(_lerp(*bounds("scale_", "xyz"), unpack_111011(np.asarray(vert["packed_scale"], dtype=np.uint32))))  # (N, 3)
        quats = unpack_rotation(vert["packed_rotation"])  # (N, 4) wxyz
        packed_color = np.asarray(vert["packed_color"], dtype=np.uint32)
        rgb = np.stack([unpack_unorm(packed_color, s, 8) for s in (24, 16, 8)], axis=1)  # (N, 3)
        if all(f in (chunk.dtype.names or ()) for f in _CHUNK_COLOR):
            rgb = _lerp(*bounds("", "rgb"), rgb)
    opacities = unpack_unorm(packed_color, 0, 8)  # (N,) already activated

    sh_rest = None
    if "sh" in names:
        sh = ply["sh"].data
        idx, k = f_rest_layout(sh.dtype.names or ())
        if len(sh) != n or not k:
            raise scene_error(path, f"compressed PLY 'sh' element must have {n} rows of f_rest_0..f_rest_{{3K-1}}; found {len(sh)} rows, {len(idx)} f_rest fields")
        sh_rest = np.empty((n, k, 3), dtype=np.float32)  # (N, K, 3), filled field by field
        fill_sh_rest(sh_rest, sh, decode=lambda u: (np.asarray(u, dtype=np.float32) / np.float32(255.0) - np.float32(0.5)) * np.float32(8.0))

    return build_splats(
        path,
        "compressed_ply",
        means=means,
        quats=quats,
        scales=scales,
        opacities=opacities,
        colors=rgb,
        sh_rest=sh_rest,
        drop_invalid=drop_invalid,
        activation={"means": "lerp over the chunk's min/max position", "scales": "exp of the lerp over the chunk's log-scale range", "colors": "lerp over the chunk's colour range"},
    )
