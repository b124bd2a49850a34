"""Scene loading and saving: pick the reader from the extension and the file's content.

==================  ====================================================  =================
extension           content                                               ``source_format``
==================  ====================================================  =================
``.ply``            header has ``chunk`` + packed ``vertex`` fields       ``compressed_ply``
``.ply``            ``vertex`` with ``scale_0..2``                        ``inria``
``.ply``            ``vertex`` with ``scale_0, scale_1`` only             ``2dgs``
``.splat``          antimatter15 32-byte records                          ``splat``
``.spz``            Niantic: gzip (versions 2, 3) or NGSP + zstd (4)      ``spz``
``.pt .ckpt .pth``  gsplat checkpoint (torch)                             ``gsplat_ckpt``
==================  ====================================================  =================

Compressed data (``.spz``) is inflated incrementally into buffers of the exact size the header
fixes, so a decompression bomb is rejected without using more memory than an honest file. Large
``.ply`` files are read block by block into preallocated float32 arrays (peak memory: the output
arrays plus one block).

Positions keep the file's frame (INRIA-style captures are y-down; ``.spz`` is converted from
RUB to that convention); see :mod:`splatplan.scenes.transforms` to change it.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable
from pathlib import Path

from ..errors import SceneFormatError
from .filters import filter_floaters as _filter_floaters
from .io_checkpoint import read_gsplat_checkpoint
from .io_common import scene_error
from .io_compressed_ply import decode_compressed_ply
from .io_ply import decode_gaussian_ply, ply_kind, read_plydata, write_gaussian_ply
from .io_splat import read_splat
from .io_spz import read_spz, write_spz
from .splats import Splats

#: Extensions load_scene understands (lower case).
SCENE_EXTENSIONS = (".ply", ".splat", ".spz", ".pt", ".ckpt", ".pth")


def _read_ply(path: Path, *, drop_invalid: bool) -> Splats:
    ply = read_plydata(path)
    if ply_kind(ply) == "compressed_ply":
        return decode_compressed_ply(ply, path, drop_invalid=drop_invalid)
    return decode_gaussian_ply(ply, path, drop_invalid=drop_invalid)  # names missing fields if not a splat PLY


_READERS: dict[str, Callable[..., Splats]] = {
    ".ply": _read_ply,
    ".splat": read_splat,
    ".spz": read_spz,
    ".pt": read_gsplat_checkpoint,
    ".ckpt": read_gsplat_checkpoint,
    ".pth": read_gsplat_checkpoint,
}


def load_scene(
    path: str | Path,
    *,
    filter_floaters: bool = True,
    floater_opacity: float = 0.1,
    floater_scale_factor: float = 5.0,
    drop_invalid: bool = False,
) -> Splats:
    """Read a Gaussian-splat scene from any supported file (see the module table).

    Args:
        path: the scene file.
        filter_floaters: drop splats with opacity < ``floater_opacity`` **and** largest std >
            ``floater_scale_factor`` x the scene's median largest std; the
            :class:`~splatplan.scenes.filters.FilterReport` is stored as a dict in
            ``info["floaters"]``.
        floater_opacity: opacity threshold of the floater filter, in [0, 1].
        floater_scale_factor: size threshold of the floater filter, > 0.
        drop_invalid: drop splats with NaN/Inf values, zero quaternions or non-positive scales
            (counts in ``info["invalid_dropped"]``) instead of raising.

    Returns:
        The scene: float32 arrays, unit wxyz quaternions, linear stds, opacities in [0, 1].

    Raises:
        SceneFormatError: missing file, unknown extension, truncated or corrupt data, missing
            fields or bad values; the message names the file and the problem.
    """
    path = Path(path)
    ext = path.suffix.lower()
    from .._files import file_kind, path_error

    try:  # a long name, a device, a FIFO: named, never opened
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        raise scene_error(path, "file not found") from None
    except OSError as exc:
        raise SceneFormatError(path_error(path, exc)) from None
    if stat.S_ISDIR(st.st_mode):
        raise scene_error(path, "a directory, not a regular file")
    if not stat.S_ISREG(st.st_mode):
        raise scene_error(path, f"{file_kind(st.st_mode)}, not a regular file")
    if ext not in _READERS:
        raise scene_error(path, f"unknown scene extension '{path.suffix}'; supported: {', '.join(SCENE_EXTENSIONS)}")
    splats = _READERS[ext](path, drop_invalid=drop_invalid)
    if filter_floaters:
        splats, report = _filter_floaters(splats, floater_opacity, floater_scale_factor)
        splats.info["floaters"] = report.as_dict()
    return splats


def save_scene(splats: Splats, path: str | Path) -> None:
    """Write ``splats`` atomically, in the format given by the extension.

    * ``.ply``: binary INRIA 3DGS (2DGS for disks), lossless for float32 data; see
      :func:`splatplan.scenes.io_ply.write_gaussian_ply`.
    * ``.spz``: Niantic version 4 (NGSP header + zstd streams), lossy (about 10x smaller); see
      :func:`splatplan.scenes.io_spz.write_spz` for the quantisation and for writing version 3.

    Raises:
        SceneFormatError: another extension, or the file cannot be written.
        SplatplanError: the scene holds bad values.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext == ".spz":
        write_spz(splats, path)
        return
    if ext != ".ply":
        raise scene_error(path, f"save_scene writes INRIA .ply or Niantic .spz (version 4); got extension '{path.suffix}'")
    write_gaussian_ply(splats, path)
