"""Test-only encoders for the formats splatplan reads but does not write, and random scenes.

Each encoder is written from the format description in the matching reader's module docstring,
independently of the reader's code, so a round trip checks the two against each other.
"""

from __future__ import annotations

import gzip
import struct
from pathlib import Path

import numpy as np
import plyfile

from splatplan.scenes import SH_C0, Splats

SQRT1_2 = np.sqrt(0.5)


def random_splats(n: int, *, k_sh: int = 0, is_2d: bool = False, seed: int = 0) -> Splats:
    """n random anisotropic splats: means in [-2, 2]^3, stds 1e-3..1e-1, any orientation."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    s = np.exp(rng.uniform(np.log(1e-3), np.log(1e-1), size=(n, 3)))
    if is_2d:
        s[:, 2] = 0.0
    return Splats(
        means=rng.uniform(-2, 2, size=(n, 3)),
        quats=q,
        scales=s,
        opacities=rng.uniform(0.01, 0.99, size=n),
        colors=rng.uniform(0.0, 1.0, size=(n, 3)),
        sh_rest=rng.uniform(-0.5, 0.5, size=(n, k_sh, 3)) if k_sh else None,
    )


def _unorm(x: np.ndarray, bits: int) -> np.ndarray:
    t = (1 << bits) - 1
    return np.clip(np.floor(np.asarray(x, dtype=np.float64) * t + 0.5), 0, t).astype(np.uint32)


def _fraction(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    span = hi - lo
    return np.where(span > 0, (x - lo) / np.where(span > 0, span, 1.0), 0.0)


def pack_rotation_wxyz(q: np.ndarray) -> np.ndarray:
    """Smallest-three 2+10+10+10 packing of wxyz quaternions (N, 4) -> uint32 (N,)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    largest = np.argmax(np.abs(q), axis=1)
    q = q * np.where(q[np.arange(len(q)), largest] < 0, -1.0, 1.0)[:, None]
    out = largest.astype(np.uint32)
    for i in range(4):
        v = _unorm(q[:, i] * SQRT1_2 + 0.5, 10)
        out = np.where(largest != i, (out << np.uint32(10)) | v, out)
    return out


def write_compressed_ply(splats: Splats, path: Path, *, with_color_range: bool = True) -> None:
    """Write a PlayCanvas/SuperSplat compressed PLY (256 splats per chunk)."""
    n = len(splats)
    n_chunks = -(-n // 256)
    log_s = np.log(splats.scales.astype(np.float64))
    chunk_fields = [f"{m}_{a}" for m in ("min", "max") for a in "xyz"] + [f"{m}_scale_{a}" for m in ("min", "max") for a in "xyz"]
    if with_color_range:
        chunk_fields += [f"{m}_{c}" for m in ("min", "max") for c in "rgb"]
    chunk = np.zeros(n_chunks, dtype=[(f, "<f4") for f in chunk_fields])
    vert = np.zeros(n, dtype=[(f, "<u4") for f in ("packed_position", "packed_rotation", "packed_scale", "packed_color")])
    for c in range(n_chunks):
        sl = slice(256 * c, min(n, 256 * (c + 1)))
        rows = {"": splats.means[sl].astype(np.float64), "scale_": log_s[sl]}
        packed = {}
        for prefix, x in rows.items():
            lo, hi = x.min(0), x.max(0)
            for j, a in enumerate("xyz"):
                chunk[f"min_{prefix}{a}"][c], chunk[f"max_{prefix}{a}"][c] = lo[j], hi[j]
            # bounds as stored (float32) so the fractions match what the reader lerps with
            lo, hi = lo.astype(np.float32).astype(np.float64), hi.astype(np.float32).astype(np.float64)
            f = _fraction(x, lo, hi)
            packed[prefix] = (_unorm(f[:, 0], 11) << np.uint32(21)) | (_unorm(f[:, 1], 10) << np.uint32(11)) | _unorm(f[:, 2], 11)
        vert["packed_position"][sl] = packed[""]
        vert["packed_scale"][sl] = packed["scale_"]
        rgb = splats.colors[sl].astype(np.float64)
        if with_color_range:
            lo, hi = rgb.min(0), rgb.max(0)
            for j, ch in enumerate("rgb"):
                chunk[f"min_{ch}"][c], chunk[f"max_{ch}"][c] = lo[j], hi[j]
            rgb = _fraction(rgb, lo.astype(np.float32).astype(np.float64), hi.astype(np.float32).astype(np.float64))
        vert["packed_color"][sl] = (
            (_unorm(rgb[:, 0], 8) << np.uint32(24))
            | (_unorm(rgb[:, 1], 8) << np.uint32(16))
            | (_unorm(rgb[:, 2], 8) << np.uint32(8))
            | _unorm(splats.opacities[sl], 8)
        )
    vert["packed_rotation"] = pack_rotation_wxyz(splats.quats.astype(np.float64))
    elements = [plyfile.PlyElement.describe(chunk, "chunk"), plyfile.PlyElement.describe(vert, "vertex")]
    if splats.sh_rest is not None:
        k = splats.sh_rest.shape[1]
        flat = splats.sh_rest.transpose(0, 2, 1).reshape(n, 3 * k)  # channel-major
        sh = np.zeros(n, dtype=[(f"f_rest_{i}", "u1") for i in range(3 * k)])
        for i in range(3 * k):
            sh[f"f_rest_{i}"] = _unorm(flat[:, i] / 8.0 + 0.5, 8)
        elements.append(plyfile.PlyElement.describe(sh, "sh"))
    plyfile.PlyData(elements, text=False, byte_order="<").write(str(path))


def write_splat(splats: Splats, path: Path) -> None:
    """Write an antimatter15 .splat file (32 bytes per splat)."""
    n = len(splats)
    rec = np.zeros(n, dtype=[("p", "<f4", (3,)), ("s", "<f4", (3,)), ("c", "u1", (4,)), ("q", "u1", (4,))])
    rec["p"] = splats.means
    rec["s"] = splats.scales
    rgba = np.concatenate([splats.colors, splats.opacities[:, None]], axis=1)
    rec["c"] = np.clip(np.round(rgba * 255), 0, 255)
    q = splats.quats / np.linalg.norm(splats.quats, axis=1, keepdims=True)
    rec["q"] = np.clip(np.round(q * 128 + 128), 0, 255)
    path.write_bytes(rec.tobytes())


def _pack_rotation_v3(xyzw: np.ndarray) -> np.ndarray:
    """spz v3 smallest-three: (N, 4) xyzw -> uint32 (N,)."""
    largest = np.argmax(np.abs(xyzw), axis=1)
    negate = xyzw[np.arange(len(xyzw)), largest] < 0
    out = largest.astype(np.uint32)
    for i in range(4):
        neg = ((xyzw[:, i] < 0) ^ negate).astype(np.uint32)
        mag = np.floor(511 * np.abs(xyzw[:, i]) / SQRT1_2 + 0.5).astype(np.uint32)
        out = np.where(largest != i, (out << np.uint32(10)) | (neg << np.uint32(9)) | mag, out)
    return out


SPZ_SH_DEGREE = {0: 0, 3: 1, 8: 2, 15: 3, 24: 4}


def spz_streams(
    *,
    means_rub: np.ndarray,  # (N, 3) RUB
    quats_rub_wxyz: np.ndarray,  # (N, 4)
    log_scales: np.ndarray,  # (N, 3)
    opacities: np.ndarray,  # (N,)
    f_dc: np.ndarray,  # (N, 3)
    sh_rub: np.ndarray | None,  # (N, K, 3)
    version: int = 2,
    frac_bits: int = 12,
) -> list[bytes]:
    """The uncompressed .spz attribute streams: positions, alphas, colours, scales, rotations[, sh]."""
    fixed = np.round(np.asarray(means_rub, dtype=np.float64) * (1 << frac_bits)).astype(np.int64) & 0xFFFFFF  # (N, 3)
    parts = [np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, (fixed >> 16) & 0xFF], axis=-1).astype(np.uint8).tobytes()]
    parts.append(np.clip(np.round(opacities * 255), 0, 255).astype(np.uint8).tobytes())
    parts.append(np.clip(np.round(f_dc * 0.15 * 255 + 127.5), 0, 255).astype(np.uint8).tobytes())
    parts.append(np.clip(np.round((log_scales + 10) * 16), 0, 255).astype(np.uint8).tobytes())
    q = quats_rub_wxyz / np.linalg.norm(quats_rub_wxyz, axis=1, keepdims=True)
    xyzw = np.concatenate([q[:, 1:], q[:, :1]], axis=1)
    if version == 2:
        xyzw = xyzw * np.where(xyzw[:, 3:] < 0, -1.0, 1.0)
        parts.append(np.clip(np.round((xyzw[:, :3] + 1) * 127.5), 0, 255).astype(np.uint8).tobytes())
    else:
        parts.append(_pack_rotation_v3(xyzw).astype("<u4").tobytes())
    if sh_rub is not None and sh_rub.shape[1]:
        parts.append(np.clip(np.round(sh_rub * 128 + 128), 0, 255).astype(np.uint8).tobytes())
    return parts


def ext_record(ext_type: int, payload: bytes) -> bytes:
    """One spz extension record: u32 type, u32 byte length, payload."""
    return struct.pack("<II", ext_type, len(payload)) + payload


def write_spz_raw(
    path: Path,
    *,
    means_rub: np.ndarray,  # (N, 3) RUB
    quats_rub_wxyz: np.ndarray,  # (N, 4)
    log_scales: np.ndarray,  # (N, 3)
    opacities: np.ndarray,  # (N,)
    f_dc: np.ndarray,  # (N, 3)
    sh_rub: np.ndarray | None,  # (N, K, 3)
    version: int = 2,
    frac_bits: int = 12,
    header_override: dict | None = None,
    payload_trim: int = 0,
    extensions: bytes = b"",
    flags: int = 0,
) -> None:
    """Write a gzip .spz (v2/v3 layout) from arrays already in spz's RUB axes; ``extensions`` are appended after the streams."""
    n = len(means_rub)
    k = 0 if sh_rub is None else sh_rub.shape[1]
    hdr = dict(magic=0x5053474E, version=version, n=n, sh_degree=SPZ_SH_DEGREE[k], frac=frac_bits, flags=flags, reserved=0)
    hdr.update(header_override or {})
    parts = [struct.pack("<IIIBBBB", *hdr.values())]
    parts += spz_streams(means_rub=means_rub, quats_rub_wxyz=quats_rub_wxyz, log_scales=log_scales, opacities=opacities, f_dc=f_dc, sh_rub=sh_rub, version=version, frac_bits=frac_bits)
    payload = b"".join(parts) + extensions
    path.write_bytes(gzip.compress(payload[: len(payload) - payload_trim]))


def write_spz_v4_raw(
    path: Path,
    streams: list[bytes],
    *,
    n: int,
    sh_degree: int,
    frac_bits: int = 12,
    flags: int = 0,
    extensions: bytes = b"",
    header_override: dict | None = None,
    toc_override: dict | None = None,
    compressed: list[bytes] | None = None,
    tail: bytes = b"",
) -> None:
    """Write a version-4 .spz: 32-byte NGSP header, extension zone, table of contents, zstd streams.

    ``toc_override`` maps a stream index to a (compressed, uncompressed) pair to declare instead;
    ``compressed`` replaces the zstd frames (e.g. a bomb); ``tail`` is appended after them.
    """
    import zstandard

    comp = compressed if compressed is not None else [zstandard.ZstdCompressor(level=3).compress(b) for b in streams]
    hdr = dict(magic=0x5053474E, version=4, n=n, sh_degree=sh_degree, frac=frac_bits, flags=flags, n_streams=len(comp), toc_offset=32 + len(extensions))
    hdr.update(header_override or {})
    head = struct.pack("<IIIBBBBI", *hdr.values()) + b"\0" * 12
    toc = []
    for i, (c, u) in enumerate(zip(comp, streams)):
        cs, us = (toc_override or {}).get(i, (len(c), len(u)))
        toc.append(struct.pack("<QQ", cs, us))
    path.write_bytes(head + extensions + b"".join(toc) + b"".join(comp) + tail)


#: Sign of the INRIA-order SH coefficients (bands 1..3) under (x, y, z) -> (x, -y, -z).
SH_PARITY_YZ = np.array([-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1], dtype=np.float64)


def _rub_arrays(splats: Splats) -> dict:
    """``splats`` (RDF axes) converted to RUB by (x, y, z) -> (x, -y, -z), as spz encoder inputs."""
    q = splats.quats.astype(np.float64) * np.array([1, 1, -1, -1])
    sh = None if splats.sh_rest is None else splats.sh_rest * SH_PARITY_YZ[: splats.sh_rest.shape[1], None]
    return dict(
        means_rub=splats.means * np.array([1, -1, -1]),
        quats_rub_wxyz=q,
        log_scales=np.log(splats.scales.astype(np.float64)),
        opacities=splats.opacities,
        f_dc=(splats.colors.astype(np.float64) - 0.5) / SH_C0,
        sh_rub=sh,
    )


def write_spz(splats: Splats, path: Path, *, version: int = 2, frac_bits: int = 12, extensions: bytes = b"", flags: int = 0) -> None:
    """Write ``splats`` (RDF axes) as a gzip .spz of version 2 or 3."""
    write_spz_raw(path, **_rub_arrays(splats), version=version, frac_bits=frac_bits, extensions=extensions, flags=flags)


def write_spz_v4(splats: Splats, path: Path, *, frac_bits: int = 12, **kw) -> None:
    """Write ``splats`` (RDF axes) as a version-4 .spz with this module's encoder (independent of the library's)."""
    streams = spz_streams(**_rub_arrays(splats), version=4, frac_bits=frac_bits)
    k = 0 if splats.sh_rest is None else splats.sh_rest.shape[1]
    write_spz_v4_raw(path, streams, n=len(splats), sh_degree=SPZ_SH_DEGREE[k], frac_bits=frac_bits, **kw)


def eval_sh(sh_rest: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Bands 1..3 of the real SH (INRIA basis and order) at unit directions d: (N, K, 3), (N, 3) -> (N, 3)."""
    x, y, z = d[:, 0:1], d[:, 1:2], d[:, 2:3]
    xx, yy, zz = x * x, y * y, z * z
    basis = [
        -0.4886025119029199 * y, 0.4886025119029199 * z, -0.4886025119029199 * x,
        1.0925484305920792 * x * y, -1.0925484305920792 * y * z, 0.31539156525252005 * (2 * zz - xx - yy),
        -1.0925484305920792 * x * z, 0.5462742152960396 * (xx - yy),
        -0.5900435899266435 * y * (3 * xx - yy), 2.890611442640554 * x * y * z, -0.4570457994644658 * y * (4 * zz - xx - yy),
        0.3731763325901154 * z * (2 * zz - 3 * xx - 3 * yy), -0.4570457994644658 * x * (4 * zz - xx - yy),
        1.445305721320277 * z * (xx - yy), -0.5900435899266435 * x * (xx - 3 * yy),
    ]  # fmt: skip
    k = sh_rest.shape[1]
    return sum(basis[i] * sh_rest[:, i, :] for i in range(k))
