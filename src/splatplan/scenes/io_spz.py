"""Niantic ``.spz``: reader (format versions 2, 3 and 4) and writer (versions 3 and 4).

Containers
----------
* **Versions 2 and 3**: the whole file is gzip. Decompressed, it holds a 16-byte little-endian
  header::

      uint32 magic = 0x5053474e ("NGSP")   uint32 version   uint32 numPoints
      uint8 shDegree (0..4)   uint8 fractionalBits   uint8 flags   uint8 reserved

  then the attribute streams below, back to back, and -- when flag ``0x2`` is set -- extension
  records up to the end of the payload.
* **Version 4** (what the current Niantic library writes by default): the file starts with a
  plain 32-byte header::

      uint32 magic   uint32 version = 4   uint32 numPoints
      uint8 shDegree   uint8 fractionalBits   uint8 flags   uint8 numStreams
      uint32 tocByteOffset   uint8 reserved[12]

  bytes ``[32, tocByteOffset)`` hold the extension records (flag ``0x2``); at ``tocByteOffset`` a
  table of contents of ``numStreams`` entries ``(uint64 compressedSize, uint64
  uncompressedSize)``; then the streams, each compressed on its own with **zstd**, back to back
  in the same order, up to the end of the file.

Flags: ``0x1`` antialiased (ignored, it only affects rendering), ``0x2`` extensions present.
An extension record is ``uint32 type, uint32 byteLength, byteLength bytes``; records are checked
to fit and are listed in ``info["spz"]["extensions"]``, their payloads are not interpreted.

Attribute streams (for all N points in turn)
--------------------------------------------
* positions: N x 3 x 24-bit signed little-endian fixed point, value = int / 2^fractionalBits,
  so fractionalBits must lie in 0..23;
* alphas: N x u8, activated opacity = u / 255;
* colours: N x 3 x u8, SH DC coefficient f_dc = (u / 255 - 0.5) / 0.15;
* scales: N x 3 x u8, log std = u / 16 - 10;
* rotations, quaternion stored **xyzw**:
  version 2: N x 3 x u8, x, y, z = u / 127.5 - 1, w = sqrt(1 - x^2 - y^2 - z^2);
  versions 3 and 4: N x u32 "smallest three": bits 31..30 index of the largest component (xyzw
  order), then for the other three components in decreasing index order from the low bits up,
  a 10-bit field (bit 9 sign, bits 8..0 magnitude m, value m / 511 / sqrt(2));
* SH: N x K x 3 x u8 (K = 0, 3, 8, 15, 24 for degree 0..4; coefficient-major, channel inner),
  value = (u - 128) / 128.

The header's point count and SH degree fix the exact size of every stream, so each compressed
stream is decompressed incrementally into a buffer of exactly that size and rejected as soon as
it would inflate further (:func:`~splatplan.scenes.io_common.read_exact`): a decompression bomb
costs no more memory than an honest file with the same header.

Axes: spz stores RUB (x right, y up, z back); the loader converts to the INRIA/COLMAP RDF
convention (x right, y down, z forward) by the 180-degree rotation about x, diag(1, -1, -1):
positions (x, -y, -z), quaternions wxyz (w, x, -y, -z), and the SH coefficients whose basis
function is odd in (y, z) change sign. The writer applies the same map (its own inverse).
Version 1 (float16 positions) is not supported.
"""

from __future__ import annotations

import gzip
import struct
import zlib
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from .io_common import BLOCK_ROWS, build_splats, color_to_sh_dc, read_exact, scene_error, sh_dc_to_color
from .splats import Splats

SPZ_MAGIC = 0x5053474E
#: Versions the reader accepts (2 and 3 gzip, 4 NGSP + zstd).
SPZ_VERSIONS = (2, 3, 4)
#: Versions the writer produces.
SPZ_WRITE_VERSIONS = (3, 4)
LEGACY_HEADER = struct.Struct("<IIIBBBB")  # 16 bytes, inside the gzip payload (v2, v3)
V4_HEADER = struct.Struct("<IIIBBBBI12x")  # 32 bytes, plain (v4)
TOC_ENTRY = struct.Struct("<QQ")  # (compressed size, uncompressed size)
EXT_RECORD = struct.Struct("<II")  # (type, byte length)
FLAG_ANTIALIASED = 0x1
FLAG_EXTENSIONS = 0x2
#: SH coefficients per channel for SH degree 0..4.
SH_DIM = {0: 0, 1: 3, 2: 8, 3: 15, 4: 24}
#: Positions are 24-bit signed fixed point: at most 23 fractional bits.
MAX_FRACTIONAL_BITS = 23
#: Largest extension block accepted after the streams of a v2/v3 payload (the header does not
#: give its size; real records are a few bytes each).
MAX_LEGACY_EXTENSION_BYTES = 1 << 20
#: Sign of each higher SH coefficient (INRIA order, bands 1..4) under (x, y, z) -> (x, -y, -z):
#: (-1)^(l + |m|), times -1 for the sin-type (m < 0) functions.
SH_FLIP_RUB_RDF = np.array(
    [-1, -1, 1] + [-1, 1, 1, -1, 1] + [-1, 1, -1, -1, 1, -1, 1] + [-1, 1, -1, 1, 1, -1, 1, -1, 1], dtype=np.float64
)
#: Quantisation constant of the colour block.
COLOR_SCALE = 0.15
#: Order of the attribute streams.
STREAM_NAMES = ("positions", "alphas", "colors", "scales", "rotations", "sh")
_SUPPORTED = "2 and 3 (gzip) and 4 (NGSP header + zstd streams)"


def stream_sizes(n: int, sh_degree: int, version: int) -> dict[str, int]:
    """Exact byte size of every attribute stream for ``n`` points (streams of size 0 are omitted)."""
    k = SH_DIM[sh_degree]
    sizes = {"positions": 9 * n, "alphas": n, "colors": 3 * n, "scales": 3 * n, "rotations": (3 if version == 2 else 4) * n}
    if k:
        sizes["sh"] = 3 * k * n
    return sizes


def _check_header(path: str | Path, magic: int, version: int, sh_degree: int, frac_bits: int) -> None:
    if magic != SPZ_MAGIC:
        raise scene_error(path, f"bad .spz magic 0x{magic:08x} (expected 0x{SPZ_MAGIC:08x})")
    if version not in SPZ_VERSIONS:
        raise scene_error(path, f".spz version {version} is not supported (supported: {_SUPPORTED}); re-export with a current spz tool")
    if sh_degree not in SH_DIM:
        raise scene_error(path, f".spz SH degree {sh_degree} is not supported (0..4)")
    if frac_bits > MAX_FRACTIONAL_BITS:
        raise scene_error(
            path,
            f".spz fractional bits {frac_bits} is outside 0..{MAX_FRACTIONAL_BITS} (positions are 24-bit signed fixed point); the header is corrupt",
        )


def _parse_extensions(path: str | Path, raw: bytes, where: str) -> list[dict]:
    """Walk ``[u32 type][u32 byteLength][payload]`` records; every record must fit exactly."""
    records = []
    pos = 0
    while pos < len(raw):
        if len(raw) - pos < EXT_RECORD.size:
            raise scene_error(path, f".spz extension block {where} ends inside a record header ({len(raw) - pos} stray bytes); the file is corrupt")
        ext_type, length = EXT_RECORD.unpack_from(raw, pos)
        pos += EXT_RECORD.size
        if length > len(raw) - pos:
            raise scene_error(path, f".spz extension record 0x{ext_type:08x} {where} claims {length:,} bytes but only {len(raw) - pos:,} remain; the file is corrupt")
        records.append({"type": f"0x{ext_type:08x}", "bytes": int(length)})
        pos += length
    return records


def unpack_rotation_v3(packed: np.ndarray) -> np.ndarray:
    """(N, 4) xyzw quaternions from uint32 smallest-three words (see the module docstring)."""
    packed = np.asarray(packed, dtype=np.uint32)
    n = packed.shape[0]
    largest = (packed >> np.uint32(30)).astype(np.int64)  # (N,) index in xyzw order
    q = np.zeros((n, 4), dtype=np.float64)
    rows = np.arange(n)
    word = packed.copy()
    # the non-largest components, highest index first, occupy 10 bits each from the low end
    for i in (3, 2, 1, 0):
        here = largest != i
        mag = (word & np.uint32(0x1FF)).astype(np.float64) / 511.0 / np.sqrt(2.0)
        neg = ((word >> np.uint32(9)) & np.uint32(1)).astype(bool)
        q[here, i] = np.where(neg, -mag, mag)[here]
        word = np.where(here, word >> np.uint32(10), word)
    q[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - np.sum(q**2, axis=1)))
    return q


def pack_rotation_v3(xyzw: np.ndarray) -> np.ndarray:
    """uint32 (N,) smallest-three words from (N, 4) xyzw quaternions (inverse of :func:`unpack_rotation_v3`)."""
    q = np.asarray(xyzw, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    largest = np.argmax(np.abs(q), axis=1)  # (N,)
    q = q * np.where(q[np.arange(len(q)), largest] < 0, -1.0, 1.0)[:, None]  # largest >= 0
    word = largest.astype(np.uint32)
    for i in range(4):  # increasing index: the last one packed ends up in the low bits
        mag = np.minimum(np.floor(np.abs(q[:, i]) * np.sqrt(2.0) * 511.0 + 0.5), 511).astype(np.uint32)
        field = ((q[:, i] < 0).astype(np.uint32) << np.uint32(9)) | mag  # sign bit 9, magnitude bits 8..0
        word = np.where(largest != i, (word << np.uint32(10)) | field, word)
    return word.astype(np.uint32)


# ----------------------------------------------------------------------------- reading
def read_spz(path: str | Path, *, drop_invalid: bool = False) -> Splats:
    """Read a Niantic ``.spz`` file (version 2, 3 or 4) and convert it from RUB to RDF axes.

    ``info["spz"]`` records the version, the flags and the extension records found.

    Raises:
        SceneFormatError: neither gzip nor an NGSP header, truncated or corrupt compressed data,
            wrong magic, an unsupported version, SH degree or fractional-bit count, a stream size
            that does not match the header (including a decompression bomb), or bad values.
    """
    try:
        with open(path, "rb") as f:
            start = f.read(4)
    except OSError as e:
        raise scene_error(path, f"cannot read the file ({e.strerror or e})") from None
    if start == struct.pack("<I", SPZ_MAGIC):
        header, blocks, extensions = _read_v4_container(path)
    elif start[:2] == b"\x1f\x8b":
        header, blocks, extensions = _read_gzip_container(path)
    else:
        raise scene_error(
            path,
            f"cannot decompress the .spz file: it is neither gzip data (versions 2, 3) nor starts with 'NGSP' (version 4); first bytes {start!r}",
        )
    splats = _decode(path, header, blocks, drop_invalid=drop_invalid)
    splats.info["spz"] = {
        "version": header["version"],
        "fractional_bits": header["frac_bits"],
        "antialiased": bool(header["flags"] & FLAG_ANTIALIASED),
        "extensions": extensions,
    }
    return splats


def _read_gzip_container(path: str | Path) -> tuple[dict, dict[str, np.ndarray], list[dict]]:
    """Versions 2 and 3: header and streams from one gzip payload, read incrementally."""
    try:
        with open(path, "rb") as f, gzip.GzipFile(fileobj=f, mode="rb") as g:
            head = b""
            while len(head) < LEGACY_HEADER.size:
                more = g.read(LEGACY_HEADER.size - len(head))
                if not more:
                    raise scene_error(path, f".spz payload is {len(head)} bytes, shorter than the 16-byte header")
                head += more
            magic, version, n, sh_degree, frac_bits, flags, _reserved = LEGACY_HEADER.unpack(head)
            if magic == SPZ_MAGIC and version == 4:
                raise scene_error(path, f".spz version 4 must not be gzip-wrapped (its 32-byte NGSP header is plain); supported: {_SUPPORTED}")
            _check_header(path, magic, version, sh_degree, frac_bits)
            sizes = stream_sizes(n, sh_degree, version)
            total = sum(sizes.values())
            what = f".spz payload (header: {n:,} points, SH degree {sh_degree}, version {version})"
            has_ext = bool(flags & FLAG_EXTENSIONS)
            body = read_exact(g, total, path, what, allow_more=has_ext)
            extensions: list[dict] = []
            if has_ext:
                tail = g.read(MAX_LEGACY_EXTENSION_BYTES + 1)
                if len(tail) > MAX_LEGACY_EXTENSION_BYTES:
                    raise scene_error(
                        path,
                        f"{what} continues for more than {MAX_LEGACY_EXTENSION_BYTES:,} bytes of extensions after its "
                        f"{total:,} bytes of streams; the file is corrupt or a decompression bomb (stopped reading)",
                    )
                extensions = _parse_extensions(path, tail, "after the streams")
    except gzip.BadGzipFile as e:
        raise scene_error(path, f"cannot decompress the .spz file ({e}); it is not valid gzip data") from None
    except (EOFError, zlib.error) as e:
        raise scene_error(path, f"truncated or corrupt gzip stream in .spz file ({e})") from None
    except OSError as e:
        raise scene_error(path, f"cannot read the file ({e.strerror or e})") from None
    header = {"version": version, "n": n, "sh_degree": sh_degree, "frac_bits": frac_bits, "flags": flags}
    blocks, offset = {}, 0
    for name, size in sizes.items():
        blocks[name] = body[offset : offset + size]
        offset += size
    return header, blocks, extensions


def _read_v4_container(path: str | Path) -> tuple[dict, dict[str, np.ndarray], list[dict]]:
    """Version 4: plain header, table of contents, one zstd stream per attribute."""
    import zstandard

    try:
        data = Path(path).read_bytes()  # the compressed file; streams are inflated one by one
    except OSError as e:
        raise scene_error(path, f"cannot read the file ({e.strerror or e})") from None
    if len(data) < V4_HEADER.size:
        raise scene_error(path, f".spz file is {len(data)} bytes, shorter than the 32-byte NGSP header; the file is truncated")
    magic, version, n, sh_degree, frac_bits, flags, n_streams, toc_offset = V4_HEADER.unpack_from(data)
    if version != 4:
        raise scene_error(path, f".spz version {version} with a plain NGSP header is not supported (supported: {_SUPPORTED})")
    _check_header(path, magic, version, sh_degree, frac_bits)
    sizes = stream_sizes(n, sh_degree, version)
    if n_streams != len(sizes):
        raise scene_error(path, f".spz header declares {n_streams} streams but SH degree {sh_degree} needs {len(sizes)} ({', '.join(sizes)}); the file is corrupt")
    toc_end = toc_offset + n_streams * TOC_ENTRY.size
    if toc_offset < V4_HEADER.size or toc_end > len(data):
        raise scene_error(path, f".spz table of contents at byte {toc_offset:,} does not fit the {len(data):,}-byte file (it must start at byte 32 or later); the file is truncated or corrupt")
    extensions = _parse_extensions(path, data[V4_HEADER.size : toc_offset], "in the header zone") if flags & FLAG_EXTENSIONS else []

    toc = [TOC_ENTRY.unpack_from(data, toc_offset + i * TOC_ENTRY.size) for i in range(n_streams)]
    for (name, size), (_, declared) in zip(sizes.items(), toc):
        if declared != size:
            raise scene_error(
                path,
                f".spz stream '{name}' is declared as {declared:,} bytes uncompressed but the header ({n:,} points, SH degree {sh_degree}) "
                f"fixes it at {size:,}; the file is corrupt",
            )
    end = toc_end + sum(c for c, _ in toc)
    if end != len(data):
        problem = "truncated" if end > len(data) else "corrupt (extra trailing bytes)"
        raise scene_error(path, f".spz file has {len(data):,} bytes but its table of contents describes {end:,}; the file is {problem}")

    dctx = zstandard.ZstdDecompressor()
    view = memoryview(data)
    blocks, offset = {}, toc_end
    for (name, size), (csize, _) in zip(sizes.items(), toc):
        try:
            reader = dctx.stream_reader(view[offset : offset + csize], read_across_frames=True)
            blocks[name] = read_exact(reader, size, path, f".spz zstd stream '{name}' (header: {n:,} points, SH degree {sh_degree})")
        except zstandard.ZstdError as e:
            raise scene_error(path, f"corrupt zstd data in .spz stream '{name}' ({e})") from None
        offset += csize
    header = {"version": version, "n": n, "sh_degree": sh_degree, "frac_bits": frac_bits, "flags": flags}
    return header, blocks, extensions


def _decode(path: str | Path, header: dict, blocks: dict[str, np.ndarray], *, drop_invalid: bool) -> Splats:
    """Attribute streams (uint8 arrays of the exact sizes) -> Splats in RDF axes.

    Rows are decoded :data:`~splatplan.scenes.io_common.BLOCK_ROWS` at a time into preallocated
    float32 arrays, so the float64 temporaries stay one block in size.
    """
    n, version, k = header["n"], header["version"], SH_DIM[header["sh_degree"]]
    inv_scale = 1.0 / (1 << header["frac_bits"])
    means = np.empty((n, 3), dtype=np.float32)
    quats = np.empty((n, 4), dtype=np.float32)  # wxyz
    scales = np.empty((n, 3), dtype=np.float32)
    colors = np.empty((n, 3), dtype=np.float32)
    # popped, so each stream is freed as soon as it is decoded (the caller keeps no reference)
    pos_u8 = blocks.pop("positions").reshape(n, 3, 3)
    col_u8, scl_u8 = blocks.pop("colors").reshape(n, 3), blocks.pop("scales").reshape(n, 3)
    rot = blocks.pop("rotations")
    rot = rot.reshape(n, 3) if version == 2 else rot.view("<u4")
    flip = np.array([1.0, -1.0, -1.0])  # RUB -> RDF: rotate 180 degrees about x
    for a in range(0, n, BLOCK_ROWS):
        b = min(n, a + BLOCK_ROWS)
        p = pos_u8[a:b].astype(np.int32)
        fixed = p[..., 0] | (p[..., 1] << 8) | (p[..., 2] << 16)  # (M, 3) unsigned 24-bit
        fixed -= (fixed & 0x800000) << 1  # sign-extend: subtract 2^24 where bit 23 is set
        means[a:b] = fixed * (inv_scale * flip) + 0.0  # + 0.0: no -0.0 from the flip
        colors[a:b] = sh_dc_to_color((col_u8[a:b] / 255.0 - 0.5) / COLOR_SCALE)
        scales[a:b] = np.exp(scl_u8[a:b] / 16.0 - 10.0)  # always finite
        if version == 2:
            xyz = rot[a:b] / 127.5 - 1.0  # (M, 3)
            xyzw = np.concatenate([xyz, np.sqrt(np.maximum(0.0, 1.0 - np.sum(xyz**2, axis=1)))[:, None]], axis=1)
        else:
            xyzw = unpack_rotation_v3(rot[a:b])  # (M, 4)
        quats[a:b, 0] = xyzw[:, 3]
        quats[a:b, 1:] = xyzw[:, :3] * flip  # wxyz: (w, x, -y, -z)
    del pos_u8, col_u8, scl_u8, rot
    sh_rest = None
    if k:  # (N, K, 3), exact in float32; in place, so one float32 copy of the SH block
        sh_rest = blocks.pop("sh").reshape(n, k, 3).astype(np.float32)
        sh_rest -= np.float32(128.0)
        sh_rest *= (SH_FLIP_RUB_RDF[:k, None] / 128.0).astype(np.float32)  # scale, and RUB -> RDF parity
    return build_splats(
        path,
        "spz",
        means=means,
        quats=quats,
        scales=scales,
        opacities=blocks["alphas"] / np.float32(255.0),
        colors=colors,
        sh_rest=sh_rest,
        drop_invalid=drop_invalid,
    )


# ----------------------------------------------------------------------------- writing
def _auto_fractional_bits(means_abs_max: float) -> int:
    """Most fractional bits (<= 23) for which every |coordinate| fits 24-bit signed fixed point."""
    for bits in range(MAX_FRACTIONAL_BITS, -1, -1):
        if np.floor(means_abs_max * (1 << bits) + 0.5) <= (1 << 23) - 1:
            return bits
    raise SplatplanError(f"cannot write .spz: a coordinate of magnitude {means_abs_max:.4g} exceeds the 24-bit fixed-point range (|x| < 8,388,608)")


def encode_spz_streams(splats: Splats, *, version: int = 4, fractional_bits: int | None = None) -> tuple[dict, dict[str, bytes]]:
    """Quantise ``splats`` (RDF axes) into spz attribute streams (RUB axes).

    Returns:
        (header fields, {stream name: bytes}) -- see the module docstring for the encodings.

    Raises:
        SplatplanError: empty scene, bad values, an unsupported number of SH coefficients,
            coordinates beyond the fixed-point range, or fractional bits outside 0..23.
    """
    if version not in SPZ_WRITE_VERSIONS:
        raise SplatplanError(f"cannot write .spz version {version}; supported: {', '.join(map(str, SPZ_WRITE_VERSIONS))}")
    n = len(splats)
    if n == 0:
        raise SplatplanError("cannot write .spz: the scene has no splats")
    splats.validate(what="cannot write .spz")
    k = 0 if splats.sh_rest is None else int(splats.sh_rest.shape[1])
    degree = {v: d for d, v in SH_DIM.items()}.get(k)
    if degree is None:
        raise SplatplanError(f"cannot write .spz: {k} SH coefficients per channel is not an SH degree 0..4 (0, 3, 8, 15 or 24)")
    flip = np.array([1.0, -1.0, -1.0])
    means = splats.means.astype(np.float64) * flip  # (N, 3) RUB
    if fractional_bits is None:
        fractional_bits = _auto_fractional_bits(float(np.max(np.abs(means))))
    if not 0 <= fractional_bits <= MAX_FRACTIONAL_BITS:
        raise SplatplanError(f"cannot write .spz: fractional bits must lie in 0..{MAX_FRACTIONAL_BITS}, got {fractional_bits}")
    fixed = np.floor(means * (1 << fractional_bits) + 0.5).astype(np.int64)  # (N, 3)
    if np.any(np.abs(fixed) > (1 << 23) - 1):
        raise SplatplanError(f"cannot write .spz: coordinates exceed the 24-bit range at {fractional_bits} fractional bits; use fewer")
    fixed &= 0xFFFFFF
    streams = {"positions": np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, (fixed >> 16) & 0xFF], axis=-1).astype(np.uint8).tobytes()}

    def u8(x: np.ndarray) -> bytes:
        return np.clip(np.floor(x + 0.5), 0, 255).astype(np.uint8).tobytes()

    streams["alphas"] = u8(splats.opacities.astype(np.float64) * 255.0)
    streams["colors"] = u8((color_to_sh_dc(splats.colors) * COLOR_SCALE + 0.5) * 255.0)
    with np.errstate(divide="ignore"):  # a 2DGS disk's zero std becomes the smallest storable, e^-10
        streams["scales"] = u8((np.log(splats.scales.astype(np.float64)) + 10.0) * 16.0)
    q = splats.quats.astype(np.float64) * np.array([1.0, 1.0, -1.0, -1.0])  # (N, 4) wxyz RUB
    xyzw = np.concatenate([q[:, 1:], q[:, :1]], axis=1)
    streams["rotations"] = pack_rotation_v3(xyzw).astype("<u4").tobytes()
    if k and splats.sh_rest is not None:
        sh = splats.sh_rest.astype(np.float64) * SH_FLIP_RUB_RDF[:k, None]  # (N, K, 3) RUB
        streams["sh"] = u8(sh * 128.0 + 128.0)
    header = {"version": version, "n": n, "sh_degree": degree, "frac_bits": fractional_bits, "flags": 0}
    return header, streams


def write_spz(splats: Splats, path: str | Path, *, version: int = 4, fractional_bits: int | None = None, level: int = 9) -> None:
    """Write ``splats`` as a Niantic ``.spz`` file, atomically.

    Args:
        splats: the scene, RDF axes (converted to spz's RUB).
        path: output file.
        version: 4 (NGSP header + zstd streams, the default) or 3 (gzip).
        fractional_bits: fixed-point fractional bits of the positions (0..23); default: the most
            that fit the scene's largest coordinate (resolution 2^-bits scene units).
        level: zstd (v4) or gzip (v3, clipped to 9) compression level.

    The encoding is lossy: positions to 2^-fractional_bits, log-scales to 1/16, opacity, colour and
    SH to 8 bits, rotations to 9 bits + sign per component; 2DGS disks get a third std of e^-10.

    Raises:
        SplatplanError: see :func:`encode_spz_streams`, or an unsupported version.
        SceneFormatError: the file cannot be written.
    """
    from .io_ply import atomic_write

    h, streams = encode_spz_streams(splats, version=version, fractional_bits=fractional_bits)
    if version == 4:
        import zstandard

        cctx = zstandard.ZstdCompressor(level=level)
        comp = [cctx.compress(streams[name]) for name in streams]
        head = V4_HEADER.pack(SPZ_MAGIC, 4, h["n"], h["sh_degree"], h["frac_bits"], h["flags"], len(comp), V4_HEADER.size)
        toc = b"".join(TOC_ENTRY.pack(len(c), len(streams[name])) for c, name in zip(comp, streams))
        parts = [head, toc, *comp]
    else:
        payload = LEGACY_HEADER.pack(SPZ_MAGIC, version, h["n"], h["sh_degree"], h["frac_bits"], h["flags"], 0) + b"".join(streams.values())
        parts = [gzip.compress(payload, compresslevel=min(level, 9), mtime=0)]

    def write(f) -> None:
        for p in parts:
            f.write(p)

    atomic_write(path, write)
