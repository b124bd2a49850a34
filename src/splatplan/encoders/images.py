"""Reading image files for the encoders (Pillow).

``load_image(path) -> (H, W, 3) float32 RGB in [0, 1]``. Modes:

* RGB: as stored (8 bits per channel).
* RGBA / LA / PA and palette images with transparency: composited over black, rgb * alpha
  (the renderer's default background), then RGB.
* L (grey), 1 (bilevel), P (palette): converted to RGB (grey replicated to the three channels).
* anything else (CMYK, YCbCr, LAB, HSV, 16-bit or float grey I / I;16 / F): a one-line error
  asking for an 8-bit RGB file, since there is no single right conversion.

Multi-frame files (GIF, TIFF): the first frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SplatplanError

_CONVERT = {"RGB", "L", "1", "P"}
#: the most pixels an input image may have (the encoders resize to a few hundred pixels a side)
MAX_IMAGE_PIXELS = 64_000_000
_ALPHA = {"RGBA", "LA", "PA", "RGBa", "La"}


def load_image(path: str | Path) -> np.ndarray:
    """Read an image file -> (H, W, 3) float32 RGB in [0, 1]; see the module docstring for modes."""
    from .base import require

    Image = require("PIL.Image", what="reading images")
    import warnings

    from .._files import existing_file

    if Path(path).is_dir():
        raise SplatplanError(f"image {path} is not a file (a directory)")
    p = existing_file(path, "image", "an image file")  # a FIFO or a device is never opened
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)  # checked below, in one line
            im = Image.open(p)
    except Image.DecompressionBombWarning:
        raise SplatplanError(f"image {p} has over {MAX_IMAGE_PIXELS:,} pixels; scale it down first") from None
    except Image.DecompressionBombError as exc:
        raise SplatplanError(f"image {p} is too large to read safely ({exc})") from None
    except (OSError, ValueError, SyntaxError) as exc:  # UnidentifiedImageError is an OSError
        raise SplatplanError(f"image {p} is not a readable image file ({exc.__class__.__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    w, h = im.size
    if w * h > MAX_IMAGE_PIXELS:  # before decoding: a 144-Mpx PNG would take 0.4 GB as float RGB
        im.close()
        raise SplatplanError(f"image {p} has {w}x{h} = {w * h:,} pixels, over the {MAX_IMAGE_PIXELS:,} limit; scale it down first")
    try:
        with im:
            im.load()
            mode = im.mode
            if mode == "P" and "transparency" in im.info:
                im, mode = im.convert("RGBA"), "RGBA"
            if mode in _ALPHA:
                a = np.asarray(im.convert("RGBA"), dtype=np.float32) / 255.0  # (H, W, 4)
                return np.ascontiguousarray(a[..., :3] * a[..., 3:4])
            if mode not in _CONVERT:
                raise SplatplanError(f"image {p} has mode {mode!r} ({'16-bit or float grey' if mode.startswith(('I', 'F')) else 'not RGB'}); save it as 8-bit RGB, RGBA or grey")
            return np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
    except SplatplanError:
        raise
    except Image.DecompressionBombError as exc:
        raise SplatplanError(f"image {p} is too large to read safely ({exc})") from None
    except (OSError, ValueError, SyntaxError) as exc:  # UnidentifiedImageError is an OSError
        raise SplatplanError(f"image {p} is not a readable image file ({exc.__class__.__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
