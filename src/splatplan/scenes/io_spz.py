"""Niantic ``.spz`` reader (format versions 2 and 3).

The file is gzip-compressed. Decompressed, it holds a 16-byte little-endian header::

    uint32 magic = 0x5053474e ("NGSP")   uint32 version (2 or 3)   uint32 numPoints
    uint8 shDegree (0..3)   uint8 fractionalBits   uint8 flags (bit 0: antialiased)   uint8 reserved

followed by attribute blocks, each for all N points in turn:

* positions: N x 3 x 24-bit signed little-endian fixed point, value = int / 2^fractionalBits;
* alphas: N x u8, activated opacity = u / 255;
* colours: N x 3 x u8, SH DC coefficient f_dc = (u / 255 - 0.5) / 0.15;
* scales: N x 3 x u8, log std = u / 16 - 10;
* rotations, quaternion stored **xyzw**:
  version 2: N x 3 x u8, x, y, z = u / 127.5 - 1, w = sqrt(1 - x^2 - y^2 - z^2);
  version 3: N x u32 "smallest three": bits 31..30 index of the largest component (xyzw order),
  then for the other three components in decreasing index order from the low bits up, a
  10-bit field (bit 9 sign, bits 8..0 magnitude m, value m / 511 / sqrt(2));
* SH: N x K x 3 x u8 (K = 0, 3, 8, 15 for degree 0..3; coefficient-major, channel inner),
  value = (u - 128) / 128.

Axes: spz stores RUB (x right, y up, z back); the loader converts to the INRIA/COLMAP RDF
convention (x right, y down, z forward) by the 180-degree rotation about x, diag(1, -1, -1):
positions (x, -y, -z), quaternions wxyz (w, x, -y, -z), and the SH coefficients whose basis
function is odd in (y, z) change sign. Version 1 (float16 positions) is not supported. The
antialiasing flag is ignored (it only affects rendering).
"""

from __future__ import annotations

import gzip
import struct
import zlib
from pathlib import Path

import numpy as np

from .io_common import build_splats, scene_error, sh_dc_to_color
from .splats import Splats

SPZ_MAGIC = 0x5053474E
SPZ_VERSIONS = (2, 3)
SPZ_HEADER = struct.Struct("<IIIBBBB")
#: SH coefficients per channel for SH degree 0..3.
SH_DIM = {0: 0, 1: 3, 2: 8, 3: 15}
#: Sign of each higher SH coefficient (INRIA order, bands 1..3) under (x, y, z) -> (x, -y, -z).
SH_FLIP_RUB_RDF = np.array([-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1], dtype=np.float64)
#: Quantisation constant of the colour block.
COLOR_SCALE = 0.15


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


def read_spz(path: str | Path, *, drop_invalid: bool = False) -> Splats:
    """Read a Niantic ``.spz`` file and convert it from RUB to RDF axes.

    Raises:
        SceneFormatError: not gzip, truncated, wrong magic, an unsupported version or SH degree,
            a payload size that does not match the header, or bad values.
    """
    try:
        with gzip.open(path, "rb") as f:
            raw = f.read()
    except gzip.BadGzipFile as e:
        raise scene_error(path, f"cannot decompress the .spz file ({e}); it is not gzip data") from None
    except OSError as e:
        raise scene_error(path, f"cannot read the file ({e.strerror or e})") from None
    except (EOFError, zlib.error) as e:
        raise scene_error(path, f"truncated or corrupt gzip stream in .spz file ({e})") from None
    if len(raw) < SPZ_HEADER.size:
        raise scene_error(path, f".spz payload is {len(raw)} bytes, shorter than the 16-byte header")
    magic, version, n, sh_degree, frac_bits, _flags, _reserved = SPZ_HEADER.unpack_from(raw)
    if magic != SPZ_MAGIC:
        raise scene_error(path, f"bad .spz magic 0x{magic:08x} (expected 0x{SPZ_MAGIC:08x})")
    if version not in SPZ_VERSIONS:
        raise scene_error(path, f".spz version {version} is not supported (supported: {', '.join(map(str, SPZ_VERSIONS))}); re-export with a current spz tool")
    if sh_degree not in SH_DIM:
        raise scene_error(path, f".spz SH degree {sh_degree} is not supported (0..3)")
    k = SH_DIM[sh_degree]
    rot_bytes = 3 if version == 2 else 4
    sizes = {"positions": 9 * n, "alphas": n, "colors": 3 * n, "scales": 3 * n, "rotations": rot_bytes * n, "sh": 3 * k * n}
    expected = SPZ_HEADER.size + sum(sizes.values())
    if len(raw) != expected:
        raise scene_error(path, f".spz payload is {len(raw)} bytes but the header ({n} points, SH degree {sh_degree}, version {version}) needs {expected}; the file is truncated or corrupt")
    blocks = {}
    offset = SPZ_HEADER.size
    for name, size in sizes.items():
        blocks[name] = np.frombuffer(raw, dtype=np.uint8, count=size, offset=offset)
        offset += size

    b = blocks["positions"].reshape(n, 3, 3).astype(np.int32)
    fixed = b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)  # (N, 3) unsigned 24-bit
    fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
    means = fixed.astype(np.float64) / (1 << frac_bits)  # (N, 3) RUB
    f_dc = (blocks["colors"].reshape(n, 3) / 255.0 - 0.5) / COLOR_SCALE  # (N, 3)
    scales = np.exp(blocks["scales"].reshape(n, 3) / 16.0 - 10.0)  # (N, 3)
    if version == 2:
        xyz = blocks["rotations"].reshape(n, 3) / 127.5 - 1.0  # (N, 3)
        w = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xyz**2, axis=1)))
        xyzw = np.concatenate([xyz, w[:, None]], axis=1)  # (N, 4)
    else:
        xyzw = unpack_rotation_v3(blocks["rotations"].view("<u4"))
    quats = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)  # (N, 4) wxyz, RUB
    sh_rest = None
    if k:
        sh_rest = (blocks["sh"].reshape(n, k, 3).astype(np.float64) - 128.0) / 128.0  # (N, K, 3) RUB

    # RUB -> RDF: rotate 180 degrees about x
    means[:, 1:] *= -1.0
    quats[:, 2:] *= -1.0
    if sh_rest is not None:
        sh_rest *= SH_FLIP_RUB_RDF[:k, None]
    return build_splats(
        path,
        "spz",
        means=means,
        quats=quats,
        scales=scales,
        opacities=blocks["alphas"] / 255.0,
        colors=sh_dc_to_color(f_dc),
        sh_rest=sh_rest,
        drop_invalid=drop_invalid,
    )
