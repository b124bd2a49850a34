"""antimatter15 ``.splat`` reader.

A headerless array of 32-byte little-endian records, one per splat:

=======  ==========  ===========================================================
bytes    type        meaning
=======  ==========  ===========================================================
0..11    3 x f32     position x, y, z (scene units, the capture's frame)
12..23   3 x f32     **linear** standard deviations (not log)
24..27   4 x u8      R, G, B colour (0.5 + C0 * f_dc, x255) and A = opacity x255
28..31   4 x u8      quaternion **wxyz**, each component stored as q * 128 + 128
=======  ==========  ===========================================================

No higher SH bands are stored.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .io_common import build_splats, scene_error
from .splats import Splats

#: One record of a .splat file.
SPLAT_DTYPE = np.dtype([("position", "<f4", (3,)), ("scale", "<f4", (3,)), ("rgba", "u1", (4,)), ("rot", "u1", (4,))])


def read_splat(path: str | Path, *, drop_invalid: bool = False) -> Splats:
    """Read an antimatter15 ``.splat`` file.

    Raises:
        SceneFormatError: empty file, a size that is not a multiple of 32 bytes, or bad values.
    """
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise scene_error(path, f"cannot read the file ({e.strerror or e})") from None
    if len(raw) == 0:
        raise scene_error(path, "empty .splat file (no splats)")
    if len(raw) % SPLAT_DTYPE.itemsize:
        raise scene_error(
            path,
            f".splat size {len(raw)} bytes is not a multiple of {SPLAT_DTYPE.itemsize} bytes per splat; "
            f"the file is truncated or not a .splat file",
        )
    rec = np.frombuffer(raw, dtype=SPLAT_DTYPE)
    rgba = rec["rgba"].astype(np.float64) / 255.0  # (N, 4)
    return build_splats(
        path,
        "splat",
        means=rec["position"],
        quats=(rec["rot"].astype(np.float64) - 128.0) / 128.0,  # (N, 4) wxyz
        scales=rec["scale"],
        opacities=rgba[:, 3],
        colors=rgba[:, :3],
        drop_invalid=drop_invalid,
    )
