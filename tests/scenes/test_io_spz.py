"""Niantic .spz: the real version-4 file, v4 write/read, v2/v3/v4 extensions, decompression bombs,
header checks (versions, fractional bits, stream tables) and the SH parity of the axis change."""

from __future__ import annotations

import gzip
import struct
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest
import zstandard

from splatplan.errors import SceneFormatError, SplatplanError
from splatplan.scenes import load_scene, save_scene
from splatplan.scenes.io_spz import SH_FLIP_RUB_RDF, read_spz, write_spz

from .scene_encoders import ext_record, random_splats, spz_streams, write_spz_raw, write_spz_v4, write_spz_v4_raw
from .scene_encoders import write_spz as write_spz_test_encoder  # independent v2/v3 encoder
from .test_io_real_files import assert_sane, thin_axis_alignment
from .test_io_roundtrip import SH_C0_OVER_SPZ, assert_same

BIKER = Path(__file__).resolve().parents[1] / "data" / "playcanvas_biker.spz"


# ----------------------------------------------------------------------------- the real v4 file
def test_biker_v4_real_file():
    s = load_scene(BIKER, filter_floaters=False)
    assert s.source_format == "spz"
    assert s.info["spz"] == {"version": 4, "fractional_bits": 12, "antialiased": False, "extensions": []}
    assert_sane(s, 152_746)
    assert s.sh_rest is None  # SH degree 0
    lo, hi = s.bounds()
    extent = hi - lo
    assert np.all(extent > 0.5) and np.all(extent < 10.0)  # an object capture a few units across
    assert hi[1] <= 1e-3 and lo[1] < -2.0  # RDF (y down): the bike stands on y = 0 and rises to negative y
    assert 1e-4 < np.median(s.scales) < 0.05
    assert 0.0 < np.median(s.opacities) < 1.0
    assert np.all((s.colors > -0.5) & (s.colors < 1.5))
    # rotations are xyzw smallest-three as in v3: the thin axes follow the surfaces, and reading
    # them with the wrong component order does visibly worse
    q = s.quats.astype(np.float64)
    right, wrong = thin_axis_alignment(s, q), thin_axis_alignment(s, np.concatenate([q[:, 3:], q[:, :3]], axis=1))
    assert right > 0.6 and right > wrong + 0.1


def test_biker_v4_rewrite_roundtrip(tmp_path):
    """Writing the real scene back as v4 and v3 reproduces it to within one quantisation step."""
    s = load_scene(BIKER, filter_floaters=False)
    for version in (4, 3):
        write_spz(s, tmp_path / f"b{version}.spz", version=version, fractional_bits=12)
        back = load_scene(tmp_path / f"b{version}.spz", filter_floaters=False)
        assert back.info["spz"]["version"] == version
        np.testing.assert_array_equal(back.means, s.means)  # same grid: exact
        np.testing.assert_array_equal(back.scales, s.scales)
        np.testing.assert_array_equal(back.opacities, s.opacities)
        np.testing.assert_allclose(back.colors, s.colors, atol=1e-6)
        assert np.all(np.abs(np.sum(back.quats * s.quats, axis=1)) > 1 - 1e-6)


# ----------------------------------------------------------------------------- write / read
@pytest.mark.parametrize("k_sh", [0, 3, 15, 24])
def test_v4_write_read_roundtrip(tmp_path, k_sh):
    s = random_splats(400, k_sh=k_sh, seed=20 + k_sh)
    if k_sh:
        s.sh_rest = np.clip(s.sh_rest * 2, -0.99, 0.99).astype(np.float32)
    save_scene(s, tmp_path / "s.spz")  # the .spz extension writes version 4
    assert (tmp_path / "s.spz").read_bytes()[:8] == b"NGSP\x04\x00\x00\x00"
    back = load_scene(tmp_path / "s.spz", filter_floaters=False)
    bits = back.info["spz"]["fractional_bits"]
    assert bits == 22  # automatic: the most bits that fit |x| < 2 in 24-bit signed fixed point
    assert_same(s, back, pos=0.5 / 2**bits + 1e-6, quat=2e-5, rel_scale=np.expm1(1 / 32) + 1e-5, opac=0.5 / 255 + 1e-6, color=0.5 * SH_C0_OVER_SPZ + 1e-6, sh=0.5 / 128 + 1e-6)


def test_v4_library_writer_against_test_encoder(tmp_path):
    """The library's v4 file and the independent test encoder's decode to the same scene."""
    s = random_splats(300, k_sh=8, seed=30)
    write_spz(s, tmp_path / "lib.spz", version=4, fractional_bits=12)
    write_spz_v4(s, tmp_path / "enc.spz", frac_bits=12)
    a, b = load_scene(tmp_path / "lib.spz", filter_floaters=False), load_scene(tmp_path / "enc.spz", filter_floaters=False)
    assert_same(a, b, pos=1.01 / 4096, quat=2e-5, rel_scale=np.expm1(1 / 16) + 1e-5, opac=1.01 / 255, color=1.01 * SH_C0_OVER_SPZ, sh=1.01 / 128)


def test_v3_write_read_roundtrip(tmp_path):
    s = random_splats(200, k_sh=15, seed=31)
    write_spz(s, tmp_path / "s.spz", version=3)
    assert (tmp_path / "s.spz").read_bytes()[:2] == b"\x1f\x8b"
    back = load_scene(tmp_path / "s.spz", filter_floaters=False)
    assert back.info["spz"]["version"] == 3
    assert_same(s, back, pos=0.5 / 2**22 + 1e-6, quat=2e-5, rel_scale=np.expm1(1 / 32) + 1e-5, opac=0.5 / 255 + 1e-6, color=0.5 * SH_C0_OVER_SPZ + 1e-6, sh=0.5 / 128 + 1e-6)


def test_writer_rejects_what_spz_cannot_hold(tmp_path):
    s = random_splats(10, k_sh=5, seed=32)
    with pytest.raises(SplatplanError, match="5 SH coefficients per channel is not an SH degree 0..4"):
        write_spz(s, tmp_path / "a.spz")
    s = random_splats(10, seed=33)
    s.means[0, 0] = 1e7
    with pytest.raises(SplatplanError, match="exceeds the 24-bit fixed-point range"):
        write_spz(s, tmp_path / "a.spz")
    with pytest.raises(SplatplanError, match="version 2; supported: 3, 4"):
        write_spz(random_splats(5), tmp_path / "a.spz", version=2)
    assert not (tmp_path / "a.spz").exists()


def test_sh_flip_matches_spherical_harmonic_parity():
    """SH_FLIP_RUB_RDF equals the parity of each real SH basis function (bands 1..4, INRIA order
    m = -l..l, sin type for m < 0) under (x, y, z) -> (x, -y, -z), computed with scipy."""
    from scipy import special

    rng = np.random.default_rng(0)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)

    def real_sh(l, m, v):
        theta, phi = np.arccos(v[:, 2]), np.arctan2(v[:, 1], v[:, 0])
        if hasattr(special, "sph_harm_y"):
            y = special.sph_harm_y(l, abs(m), theta, phi)
        else:  # older scipy: sph_harm(m, l, azimuth, polar)
            y = special.sph_harm(abs(m), l, phi, theta)
        return y.real if m >= 0 else y.imag

    signs = []
    for l in range(1, 5):
        for m in range(-l, l + 1):
            a, b = real_sh(l, m, d), real_sh(l, m, d * np.array([1, -1, -1]))
            ratio = b / a
            assert np.allclose(np.abs(ratio), 1.0, atol=1e-9)
            signs.append(np.sign(np.median(ratio)))
    np.testing.assert_array_equal(SH_FLIP_RUB_RDF, np.array(signs))


# ----------------------------------------------------------------------------- extensions
ADOBE_ORBIT = ext_record(0xADBE0002, struct.pack("<fff", -0.5, 0.5, 1.0))
UNKNOWN = ext_record(0x12340001, b"\x01" * 24)


@pytest.mark.parametrize("version", [2, 3])
def test_legacy_spz_with_extensions_loads(tmp_path, version):
    s = random_splats(50, k_sh=3, seed=40)
    write_spz_test_encoder(s, tmp_path / "e.spz", version=version, flags=0x2 | 0x1, extensions=ADOBE_ORBIT + UNKNOWN)
    write_spz_test_encoder(s, tmp_path / "plain.spz", version=version)
    back, plain = load_scene(tmp_path / "e.spz", filter_floaters=False), load_scene(tmp_path / "plain.spz", filter_floaters=False)
    assert back.info["spz"]["extensions"] == [{"type": "0xadbe0002", "bytes": 12}, {"type": "0x12340001", "bytes": 24}]
    assert back.info["spz"]["antialiased"]
    for name in ("means", "quats", "scales", "opacities", "colors", "sh_rest"):
        np.testing.assert_array_equal(getattr(back, name), getattr(plain, name))


def test_legacy_spz_extension_flag_without_records(tmp_path):
    write_spz_test_encoder(random_splats(5, seed=41), tmp_path / "e.spz", version=3, flags=0x2)
    assert load_scene(tmp_path / "e.spz", filter_floaters=False).info["spz"]["extensions"] == []


def test_legacy_spz_bad_extension_record(tmp_path):
    bad = struct.pack("<II", 0xADBE0002, 100) + b"\x00" * 12  # claims 100 bytes, has 12
    write_spz_test_encoder(random_splats(5, seed=42), tmp_path / "e.spz", version=3, flags=0x2, extensions=bad)
    with pytest.raises(SceneFormatError, match=r"e\.spz: \.spz extension record 0xadbe0002 after the streams claims 100 bytes but only 12 remain"):
        load_scene(tmp_path / "e.spz")
    write_spz_test_encoder(random_splats(5, seed=42), tmp_path / "f.spz", version=3, flags=0x2, extensions=b"\x01\x02\x03")
    with pytest.raises(SceneFormatError, match=r"ends inside a record header \(3 stray bytes\)"):
        load_scene(tmp_path / "f.spz")


def test_legacy_spz_trailing_bytes_without_extension_flag(tmp_path):
    write_spz_test_encoder(random_splats(5, seed=43), tmp_path / "t.spz", version=3, extensions=ADOBE_ORBIT)  # flag not set
    with pytest.raises(SceneFormatError, match=r"decompresses to more than the [\d,]+ bytes its header fixes"):
        load_scene(tmp_path / "t.spz")


def test_v4_with_header_zone_extensions(tmp_path):
    s = random_splats(60, k_sh=3, seed=44)
    write_spz_v4(s, tmp_path / "e.spz", flags=0x2, extensions=ADOBE_ORBIT + UNKNOWN)
    write_spz_v4(s, tmp_path / "plain.spz")
    back, plain = load_scene(tmp_path / "e.spz", filter_floaters=False), load_scene(tmp_path / "plain.spz", filter_floaters=False)
    assert [e["type"] for e in back.info["spz"]["extensions"]] == ["0xadbe0002", "0x12340001"]
    np.testing.assert_array_equal(back.means, plain.means)
    np.testing.assert_array_equal(back.sh_rest, plain.sh_rest)


# ----------------------------------------------------------------------------- decompression bombs
def _zero_gzip(header: bytes, n_zero_mib: int) -> bytes:
    """gzip of ``header`` followed by n MiB of zeros, built incrementally (about 1 KB per MiB)."""
    c = zlib.compressobj(9, zlib.DEFLATED, 31)
    out = [c.compress(header)]
    block = bytes(1 << 20)
    for _ in range(n_zero_mib):
        out.append(c.compress(block))
    out.append(c.flush())
    return b"".join(out)


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


@pytest.mark.parametrize("flags", [0, 0x2])
def test_gzip_spz_bomb_stops_early(tmp_path, flags):
    """A header claiming 10 points followed by 64 MiB of zeros: rejected after a few KiB of output."""
    header = struct.pack("<IIIBBBB", 0x5053474E, 3, 10, 0, 12, flags, 0)
    bomb = _zero_gzip(header, 64)
    assert len(bomb) < 100_000
    (tmp_path / "bomb.spz").write_bytes(bomb)

    def load():
        with pytest.raises(SceneFormatError, match=r"bomb\.spz: .*(decompresses to more than the 200 bytes its header fixes|more than 1,048,576 bytes of extensions).*decompression bomb"):
            load_scene(tmp_path / "bomb.spz")

    assert _peak_bytes(load) < 8 << 20  # never near the 64 MiB the stream inflates to


def test_zstd_spz_bomb_stops_early(tmp_path):
    """A v4 file whose positions stream inflates to 128 MiB while its table says 90 bytes."""
    s = random_splats(10, seed=45)
    streams = spz_streams(means_rub=s.means, quats_rub_wxyz=s.quats, log_scales=np.log(s.scales), opacities=s.opacities, f_dc=np.zeros((10, 3)), sh_rub=None, version=4)
    cctx = zstandard.ZstdCompressor(level=3)
    comp = [cctx.compress(b) for b in streams]
    chunker = zstandard.ZstdCompressor(level=19, write_content_size=False).compressobj()
    zeros = bytes(1 << 20)
    comp[0] = b"".join([chunker.compress(zeros) for _ in range(128)] + [chunker.flush()])
    assert len(comp[0]) < 100_000
    write_spz_v4_raw(tmp_path / "bomb.spz", streams, n=10, sh_degree=0, compressed=comp)

    def load():
        with pytest.raises(SceneFormatError, match=r"bomb\.spz: \.spz zstd stream 'positions' .* decompresses to more than the 90 bytes its header fixes; .*decompression bomb"):
            load_scene(tmp_path / "bomb.spz")

    assert _peak_bytes(load) < 8 << 20


def test_v4_table_claiming_more_than_the_header(tmp_path):
    s = random_splats(10, seed=46)
    streams = spz_streams(means_rub=s.means, quats_rub_wxyz=s.quats, log_scales=np.log(s.scales), opacities=s.opacities, f_dc=np.zeros((10, 3)), sh_rub=None, version=4)
    comp = [zstandard.ZstdCompressor(level=3).compress(b) for b in streams]
    write_spz_v4_raw(tmp_path / "t.spz", streams, n=10, sh_degree=0, compressed=comp, toc_override={1: (len(comp[1]), 1 << 40)})
    with pytest.raises(SceneFormatError, match=r"stream 'alphas' is declared as 1,099,511,627,776 bytes uncompressed but the header \(10 points, SH degree 0\) fixes it at 10"):
        load_scene(tmp_path / "t.spz")


def test_huge_point_count_in_a_tiny_gzip_file(tmp_path):
    (tmp_path / "h.spz").write_bytes(gzip.compress(struct.pack("<IIIBBBB", 0x5053474E, 3, 0xFFFFFFFF, 3, 12, 0, 0) + b"\x00" * 64))
    with pytest.raises(SceneFormatError, match=r"h\.spz: .*(ends after 64 of the|more than this machine can allocate)"):
        load_scene(tmp_path / "h.spz")


# ----------------------------------------------------------------------------- header checks
def _v3(path: Path, **kw) -> Path:
    s = random_splats(20, seed=47)
    write_spz_raw(path, means_rub=s.means, quats_rub_wxyz=s.quats, log_scales=np.log(s.scales), opacities=s.opacities, f_dc=np.zeros((20, 3)), sh_rub=None, version=3, **kw)
    return path


@pytest.mark.parametrize("frac", [24, 40, 255])
def test_fractional_bits_out_of_range(tmp_path, frac):
    with pytest.raises(SceneFormatError, match=rf"f\.spz: \.spz fractional bits {frac} is outside 0\.\.23 \(positions are 24-bit signed fixed point\)"):
        load_scene(_v3(tmp_path / "f.spz", header_override={"frac": frac}))
    s = random_splats(20, seed=48)
    write_spz_v4(s, tmp_path / "g.spz", header_override={"frac": frac})
    with pytest.raises(SceneFormatError, match=rf"g\.spz: \.spz fractional bits {frac} is outside 0\.\.23"):
        load_scene(tmp_path / "g.spz")


def test_fractional_bits_in_range_decode(tmp_path):
    s = random_splats(20, seed=49)
    s.means *= 0.2  # |x| < 0.5 fits 23 fractional bits
    for bits in (0, 8, 23):
        write_spz_test_encoder(s, tmp_path / "a.spz", version=3, frac_bits=bits)
        back = load_scene(tmp_path / "a.spz", filter_floaters=False)
        np.testing.assert_allclose(back.means, s.means, atol=0.5 / 2**bits + 1e-7)


@pytest.mark.parametrize("version", [1, 5, 7])
def test_unknown_versions_are_named(tmp_path, version):
    supported = r"\(supported: 2 and 3 \(gzip\) and 4 \(NGSP header \+ zstd streams\)\)"
    with pytest.raises(SceneFormatError, match=rf"v\.spz: \.spz version {version} is not supported {supported}"):
        load_scene(_v3(tmp_path / "v.spz", header_override={"version": version}))
    write_spz_v4(random_splats(5, seed=50), tmp_path / "w.spz", header_override={"version": version})
    with pytest.raises(SceneFormatError, match=rf"w\.spz: \.spz version {version} with a plain NGSP header is not supported {supported}"):
        load_scene(tmp_path / "w.spz")


def test_gzip_wrapped_version_4(tmp_path):
    with pytest.raises(SceneFormatError, match=r"version 4 must not be gzip-wrapped"):
        load_scene(_v3(tmp_path / "v.spz", header_override={"version": 4}))


def test_sh_degree_out_of_range(tmp_path):
    with pytest.raises(SceneFormatError, match=r"\.spz SH degree 5 is not supported \(0\.\.4\)"):
        load_scene(_v3(tmp_path / "d.spz", header_override={"sh_degree": 5}))


def _v4_file(path: Path, n: int = 30, **kw) -> tuple[Path, list[bytes]]:
    s = random_splats(n, k_sh=3, seed=51)
    streams = spz_streams(means_rub=s.means, quats_rub_wxyz=s.quats, log_scales=np.log(s.scales), opacities=s.opacities, f_dc=np.zeros((n, 3)), sh_rub=s.sh_rest, version=4)
    write_spz_v4_raw(path, streams, n=n, sh_degree=1, **kw)
    return path, streams


def test_v4_wrong_stream_count(tmp_path):
    path, _ = _v4_file(tmp_path / "c.spz", header_override={"n_streams": 5})
    with pytest.raises(SceneFormatError, match=r"c\.spz: \.spz header declares 5 streams but SH degree 1 needs 6 \(positions, alphas, colors, scales, rotations, sh\)"):
        load_scene(path)


def test_v4_bad_toc_offset(tmp_path):
    path, _ = _v4_file(tmp_path / "o.spz", header_override={"toc_offset": 16})
    with pytest.raises(SceneFormatError, match=r"table of contents at byte 16 does not fit"):
        load_scene(path)
    path, _ = _v4_file(tmp_path / "p.spz", header_override={"toc_offset": 10**9})
    with pytest.raises(SceneFormatError, match=r"table of contents at byte 1,000,000,000 does not fit"):
        load_scene(path)


def test_v4_truncated_and_trailing(tmp_path):
    path, _ = _v4_file(tmp_path / "t.spz")
    raw = path.read_bytes()
    path.write_bytes(raw[:-10])
    with pytest.raises(SceneFormatError, match=r"t\.spz: \.spz file has [\d,]+ bytes but its table of contents describes [\d,]+; the file is truncated"):
        load_scene(path)
    path.write_bytes(raw + b"junk")
    with pytest.raises(SceneFormatError, match=r"describes [\d,]+; the file is corrupt \(extra trailing bytes\)"):
        load_scene(path)


def test_v4_corrupt_zstd_stream(tmp_path):
    path, streams = _v4_file(tmp_path / "z.spz")
    cctx = zstandard.ZstdCompressor(level=3)
    comp = [cctx.compress(b) for b in streams]
    comp[2] = b"\x28\xb5\x2f\xfd" + b"\xff" * (len(comp[2]) - 4)  # zstd magic, garbage frame
    write_spz_v4_raw(path, streams, n=30, sh_degree=1, compressed=comp)
    with pytest.raises(SceneFormatError, match=r"z\.spz: corrupt zstd data in \.spz stream 'colors'"):
        load_scene(path)
    comp = [cctx.compress(b) for b in streams]
    comp[4] = comp[4][: len(comp[4]) // 2]  # frame cut in half
    write_spz_v4_raw(path, streams, n=30, sh_degree=1, compressed=comp)
    with pytest.raises(SceneFormatError, match=r"z\.spz: .*stream 'rotations'.*(ends after|corrupt)"):
        load_scene(path)


def test_v4_stream_shorter_than_declared(tmp_path):
    path, streams = _v4_file(tmp_path / "s.spz")
    short = list(streams)
    short[1] = short[1][:-3]  # alphas stream holds 27 bytes, the table still says 30
    comp = [zstandard.ZstdCompressor(level=3).compress(b) for b in short]
    write_spz_v4_raw(path, streams, n=30, sh_degree=1, compressed=comp)
    with pytest.raises(SceneFormatError, match=r"stream 'alphas' .* ends after 27 of the 30 bytes its header describes"):
        read_spz(path)
