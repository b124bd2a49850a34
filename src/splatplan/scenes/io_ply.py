"""INRIA 3DGS / 2DGS ``.ply``: reader, writer, and the PLY dispatch (INRIA vs 2DGS vs compressed).

Layout (binary PLY, one ``vertex`` element, fields read **by name** so their order is free):

* ``x y z`` -- centre, scene units, the capture's frame (COLMAP/INRIA: y down, z forward).
* ``f_dc_0..2`` -- SH DC per channel; colour = 0.5 + C0 * f_dc.
* ``f_rest_0..3K-1`` -- higher SH bands, **channel-major**: ``f_rest_{c*K + k}`` is coefficient k
  of channel c; stored here as ``sh_rest[:, k, c]`` (N, K, 3).
* ``opacity`` -- logit; activated with a sigmoid.
* ``scale_0..2`` -- log of the linear std; 2DGS files have only ``scale_0, scale_1`` (the third
  std is 0: a flat disk).
* ``rot_0..3`` -- quaternion wxyz, not normalised.

Other fields (``nx ny nz``, custom attributes) are ignored.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import plyfile

from ..errors import SceneFormatError, SplatplanError
from .io_common import BLOCK_ROWS, LOG_FLOAT32_MAX, build_splats, color_to_sh_dc, exp_std, f_rest_layout, fill_sh_rest, logit, scene_error, sh_dc_to_color, sigmoid
from .splats import Splats

_REQUIRED = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "rot_0", "rot_1", "rot_2", "rot_3"]


def read_plydata(path: str | Path) -> plyfile.PlyData:
    """Parse a PLY file's header and map its elements, turning every parse problem into :class:`SceneFormatError`.

    Binary elements with fixed-size rows stay memory-mapped (``np.memmap``, copy-on-write): the
    decoders copy what they need into their own arrays, field by field or block by block (see
    :func:`iter_rows`), so loading never holds a second in-memory copy of the file. Besides
    plyfile's own checks (header syntax, early end of file), a binary file whose size differs
    from header + element counts x row sizes (trailing bytes) is rejected too.
    """
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
        if magic not in (b"ply\n", b"ply\r"):
            raise scene_error(path, "not a PLY file (it does not start with 'ply')")
        _check_header_counts(path)
        # memory-mapped: plyfile's non-mmap binary path parses row by row and is ~1000x slower
        ply = plyfile.PlyData.read(str(path), mmap=True)
    except SceneFormatError:
        raise
    except plyfile.PlyElementParseError as e:
        raise scene_error(path, f"truncated or corrupt PLY data ({e}); the byte count does not match the element counts in the header") from None
    except (plyfile.PlyParseError, ValueError, TypeError, UnicodeDecodeError) as e:
        raise scene_error(path, f"invalid PLY file ({e})") from None
    except OSError as e:
        raise scene_error(path, f"cannot read the file ({e.strerror or e})") from None
    _check_no_trailing_bytes(path, ply)
    return ply


def _check_header_counts(path: str | Path) -> None:
    """The declared range of a PLY header's element counts, before any row is read: every row
    takes at least 2 bytes of an ASCII file (a digit and a separator per property) and its
    fixed row size of a binary one, so a count the file's size cannot hold (an ASCII PLY declaring
    1e12 vertices: plyfile would allocate for all of them) is one line naming the element; the
    arrays of a plausible count go through the resource guard."""
    from .._resources import require_bytes

    with open(path, "rb") as f:
        head = f.read(1 << 20)
    end = head.find(b"end_header")
    if end < 0:
        return  # plyfile names the missing end of the header
    body = os.path.getsize(path) - (head.find(b"\n", end) + 1)
    ascii_ = b"format ascii" in head[:end]
    sizes = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
             "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
    elements: list[list] = []  # [name, count, min row bytes, properties]
    for line in head[:end].decode("ascii", "replace").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element":
            try:
                elements.append([parts[1], int(parts[2]), 0, 0])
            except ValueError:
                return  # plyfile names the bad count
        elif parts[:1] == ["property"] and elements:
            elements[-1][3] += 1
            kind = parts[2] if len(parts) >= 3 and parts[1] == "list" else (parts[1] if len(parts) >= 2 else "")
            if kind not in sizes:
                return  # plyfile names the bad property
            elements[-1][2] += 2  # an ASCII row holds at least a digit and a separator per property
    if not ascii_:
        return  # binary rows are memory-mapped: plyfile's early end-of-file check holds
    for name, count, row, nprops in elements:
        if count < 0:
            raise scene_error(path, f"invalid PLY header: element '{name}' has a negative count {count}")
        if row and count * row > max(body, 0):
            raise scene_error(path, f"truncated or corrupt PLY data: the header declares {count:,} '{name}' rows of at least {row} bytes each, more than the file's "
                                    f"{max(body, 0):,} bytes of data hold (truncated or a corrupt header)")
        require_bytes(float(count) * max(nprops, 1) * 8.0, f"the {count:,} '{name}' rows of {path}", "the scene's size (split the file)")


def _header_length(path: str | Path) -> int | None:
    """Bytes up to and including the ``end_header`` line, or None if not found in the first MiB."""
    with open(path, "rb") as f:
        head = f.read(1 << 20)
    end = head.find(b"end_header")
    if end < 0:
        return None
    return head.index(b"\n", end) + 1


def _fixed_rows(ply: plyfile.PlyData) -> bool:
    """True for a binary PLY whose elements all have fixed-size rows (no list properties)."""
    return not ply.text and not any(isinstance(p, plyfile.PlyListProperty) for el in ply.elements for p in el.properties)


def _check_no_trailing_bytes(path: str | Path, ply: plyfile.PlyData) -> None:
    """Reject binary PLYs with bytes after the last element (fixed-size rows only)."""
    if not _fixed_rows(ply):
        return
    header_len = _header_length(path)
    if header_len is None:
        return
    expected = header_len + sum(el.count * el.data.dtype.itemsize for el in ply.elements)
    size = os.path.getsize(path)
    if size != expected:
        raise scene_error(path, f"file has {size} bytes but its header describes {expected}; the file is corrupt (extra trailing bytes)")


def iter_rows(ply: plyfile.PlyData, path: str | Path, name: str, block: int = BLOCK_ROWS):
    """Yield ``(start, rows)`` blocks of element ``name``'s structured rows, in order.

    For a binary PLY with fixed-size rows each block is read from the file with ordinary reads
    (not through the memory map), so the resident memory stays one block, whatever the file
    size; otherwise blocks are slices of plyfile's in-memory array.
    """
    el = ply[name]
    data = el.data
    n = len(data)
    if not (isinstance(data, np.memmap) and _fixed_rows(ply)):
        for a in range(0, n, block):
            yield a, data[a : a + block]
        return
    header_len = _header_length(path)
    offset = header_len + sum(e.count * e.data.dtype.itemsize for e in ply.elements[: ply.elements.index(el)])
    dtype = data.dtype  # structured, row size = itemsize, byte order of the file
    with open(path, "rb") as f:
        f.seek(offset)
        for a in range(0, n, block):
            m = min(block, n - a)
            raw = f.read(m * dtype.itemsize)
            if len(raw) != m * dtype.itemsize:
                raise scene_error(path, "the file changed or was truncated while it was being read")
            yield a, np.frombuffer(raw, dtype=dtype)


def ply_kind(ply: plyfile.PlyData) -> str | None:
    """'compressed_ply', 'inria', '2dgs' or None, decided by the header's elements and fields."""
    names = {el.name for el in ply.elements}
    if "vertex" not in names:
        return None
    fields = set(ply["vertex"].data.dtype.names or ())
    if "chunk" in names and "packed_position" in fields:
        return "compressed_ply"
    if {"scale_0", "scale_1"} <= fields:
        return "inria" if "scale_2" in fields else "2dgs"
    return None


def _float32_matrix(rows: np.ndarray) -> tuple[np.ndarray | None, dict[str, int]]:
    """(M, F) float32 view of structured rows whose fields are all float32 of one byte order and
    packed without gaps, with each field's column; (None, {}) for any other layout."""
    dt = rows.dtype
    names = dt.names or ()
    if not names or not rows.flags.c_contiguous or dt.itemsize != 4 * len(names):
        return None, {}
    fields = dt.fields
    if fields is None:  # (a structured dtype with names always has fields)
        return None, {}
    f0 = fields[names[0]][0]
    if f0.kind != "f" or f0.itemsize != 4 or any(fields[nm][0] != f0 or fields[nm][1] % 4 for nm in names):
        return None, {}
    col = {nm: fields[nm][1] // 4 for nm in names}
    if len(set(col.values())) != len(names):
        return None, {}
    return rows.view(f0).reshape(len(rows), len(names)), col


def _cols(col: dict[str, int], names: list[str]) -> slice | list[int]:
    """Column selector for ``names``: a slice when they are consecutive (a view, no gather)."""
    idx = [col[nm] for nm in names]
    if idx == list(range(idx[0], idx[0] + len(idx))):
        return slice(idx[0], idx[0] + len(idx))
    return idx


def decode_gaussian_ply(ply: plyfile.PlyData, path: str | Path, *, drop_invalid: bool = False) -> Splats:
    """Decode an INRIA 3DGS or 2DGS ``vertex`` element (see the module docstring).

    Memory: the output float32 arrays are allocated once and filled block by block
    (:data:`~splatplan.scenes.io_common.BLOCK_ROWS` rows at a time, activations in float64 per
    block), so the peak is the output plus one block, not several float64 copies of the SH block.

    Raises:
        SceneFormatError: missing fields (all named), a malformed ``f_rest`` set or bad values.
    """
    if "vertex" not in {el.name for el in ply.elements}:
        raise scene_error(path, "PLY has no 'vertex' element; not a Gaussian-splat file")
    v = ply["vertex"].data
    fields = set(v.dtype.names or ())
    missing = [f for f in _REQUIRED if f not in fields]
    if missing:
        raise scene_error(path, f"PLY 'vertex' element lacks required Gaussian-splat field(s) {', '.join(missing)}; expected an INRIA 3DGS or 2DGS export")
    is_2d = "scale_2" not in fields
    n = len(v)
    rest_idx, k = f_rest_layout(fields)
    if k is None:
        raise scene_error(path, f"'f_rest_*' fields must be f_rest_0..f_rest_{{3K-1}}; found {len(rest_idx)} with indices {rest_idx[0]}..{rest_idx[-1]}")

    means = np.empty((n, 3), dtype=np.float32)
    quats = np.empty((n, 4), dtype=np.float32)  # wxyz, not normalised
    scales = np.zeros((n, 3), dtype=np.float32)  # third std stays 0 for 2DGS
    opacities = np.empty(n, dtype=np.float32)
    colors = np.empty((n, 3), dtype=np.float32)
    sh_rest = np.empty((n, k, 3), dtype=np.float32) if k else None
    n_scales = 2 if is_2d else 3
    with np.errstate(over="ignore", invalid="ignore"):  # overflow -> Inf, reported by build_splats
        for a, rows in iter_rows(ply, path, "vertex"):
            b = a + len(rows)
            mat, col = _float32_matrix(rows)
            if mat is not None:  # the usual all-float32 file: gather whole column groups at once
                means[a:b] = mat[:, _cols(col, ["x", "y", "z"])]
                quats[a:b] = mat[:, _cols(col, [f"rot_{j}" for j in range(4)])]
                scales[a:b, :n_scales] = exp_std(mat[:, _cols(col, [f"scale_{j}" for j in range(n_scales)])])
                opacities[a:b] = sigmoid(mat[:, col["opacity"]])
                colors[a:b] = sh_dc_to_color(mat[:, _cols(col, [f"f_dc_{c}" for c in range(3)])])
                if sh_rest is not None:  # (k > 0) (M, 3K) channel-major -> (M, K, 3)
                    sh_rest[a:b] = mat[:, _cols(col, [f"f_rest_{i}" for i in range(3 * k)])].reshape(b - a, 3, k).transpose(0, 2, 1)
                continue
            for j, axis in enumerate("xyz"):
                means[a:b, j] = rows[axis]
            for j in range(4):
                quats[a:b, j] = rows[f"rot_{j}"]
            for j in range(n_scales):
                scales[a:b, j] = exp_std(rows[f"scale_{j}"])
            opacities[a:b] = sigmoid(rows["opacity"])
            for c in range(3):
                colors[a:b, c] = sh_dc_to_color(rows[f"f_dc_{c}"])
            if sh_rest is not None:  # (k > 0)
                fill_sh_rest(sh_rest[a:b], rows)
        rows = mat = None  # release the last block before validating
    return build_splats(
        path,
        "2dgs" if is_2d else "inria",
        means=means,
        quats=quats,
        scales=scales,
        opacities=opacities,
        colors=colors,
        sh_rest=sh_rest,
        is_2d=is_2d,
        drop_invalid=drop_invalid,
        activation={
            "scales": f"std = exp(scale_*); log-scales above {LOG_FLOAT32_MAX:.1f} overflow",
            "opacities": "sigmoid(opacity)",
            "colors": "0.5 + C0 * f_dc_*",
        },
    )


def write_gaussian_ply(splats: Splats, path: str | Path) -> None:
    """Write ``splats`` as a binary little-endian INRIA 3DGS ``.ply``, atomically.

    Opacity is written as a logit (opacities clipped to [1e-7, 1 - 1e-7] so it is finite), scales
    as logs, ``f_dc`` from the colours, ``f_rest`` channel-major when ``sh_rest`` is present and
    ``nx ny nz = 0`` for tools that expect them. A scene of 2DGS disks (every third scale 0) is
    written as a 2DGS file with only ``scale_0, scale_1``.

    The data go to a temporary file in the target directory, which then replaces ``path``
    (``os.replace``), so a failure never leaves a half-written file behind.

    Raises:
        SplatplanError: the scene is empty, has bad values or mixes disks with 3D splats.
        SceneFormatError: the file cannot be written.
    """
    n = len(splats)
    if n == 0:
        raise SplatplanError(f"cannot write {path}: the scene has no splats")
    splats.validate(what=f"cannot write {path}")
    is_2d = splats.is_2d
    if not is_2d and np.any(splats.scales[:, 2] == 0):
        raise SplatplanError(f"cannot write {path}: some (not all) splats have a zero third scale; a PLY holds either 3DGS splats or 2DGS disks")
    k = 0 if splats.sh_rest is None else splats.sh_rest.shape[1]
    n_scales = 2 if is_2d else 3
    names = (
        ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
        + [f"f_rest_{i}" for i in range(3 * k)]
        + ["opacity"]
        + [f"scale_{i}" for i in range(n_scales)]
        + [f"rot_{i}" for i in range(4)]
    )
    data = np.empty(n, dtype=[(name, "<f4") for name in names])
    for i, axis in enumerate("xyz"):
        data[axis] = splats.means[:, i]
        data[f"n{axis}"] = 0.0
    f_dc = color_to_sh_dc(splats.colors)  # (N, 3)
    for c in range(3):
        data[f"f_dc_{c}"] = f_dc[:, c]
    if k and splats.sh_rest is not None:
        flat = splats.sh_rest.transpose(0, 2, 1).reshape(n, 3 * k)  # (N, 3K) channel-major
        for i in range(3 * k):
            data[f"f_rest_{i}"] = flat[:, i]
    data["opacity"] = logit(splats.opacities)
    for i in range(n_scales):
        data[f"scale_{i}"] = np.log(splats.scales[:, i].astype(np.float64))
    q = splats.quats / np.linalg.norm(splats.quats, axis=1, keepdims=True)  # (N, 4) wxyz
    for i in range(4):
        data[f"rot_{i}"] = q[:, i]
    ply = plyfile.PlyData([plyfile.PlyElement.describe(data, "vertex")], text=False, byte_order="<")
    atomic_write(path, ply.write)


def atomic_write(path: str | Path, write) -> None:
    """Call ``write(binary_file)`` on a temporary file next to ``path``, then move it into place.

    Raises:
        SceneFormatError: the directory does not exist or is not writable.
    """
    from .._files import output_target, publish

    given = Path(path)
    try:
        dest, special = output_target(given)
    except SplatplanError as e:
        raise scene_error(given, f"cannot write here ({e})") from None
    path = dest
    mode = (path.stat().st_mode & 0o777) if path.exists() and not special else 0o644
    try:
        fd, tmp = tempfile.mkstemp(dir=tempfile.gettempdir() if special else path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as e:
        raise scene_error(given, f"cannot write here ({e.strerror or e})") from None
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        try:
            publish(tmp, given, mode)
        except SplatplanError as e:
            raise SceneFormatError(str(e)) from None
    except BaseException as e:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(e, OSError):
            raise scene_error(path, f"cannot write the file ({e.strerror or e})") from None
        raise
