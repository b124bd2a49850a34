"""Broken inputs give a SceneFormatError that names the file and the problem, never a raw traceback."""

from __future__ import annotations

import gzip
import sys
from pathlib import Path

import numpy as np
import plyfile
import pytest

from splatplan.errors import SceneFormatError, SplatplanError
from splatplan.scenes import load_scene, save_scene

from .scene_encoders import random_splats, write_compressed_ply, write_splat, write_spz, write_spz_raw

BANANA = Path(__file__).resolve().parents[1] / "data" / "equinor_banana_splat.ply"


def _inria_ply(path: Path, n: int = 20, *, drop: tuple[str, ...] = (), edit=None) -> Path:
    """Write a small INRIA ply, optionally without some fields or with edited values."""
    save_scene(random_splats(n, seed=1), path)
    data = plyfile.PlyData.read(str(path), mmap=False)["vertex"].data
    names = [f for f in data.dtype.names if f not in drop]
    out = np.empty(len(data), dtype=[(f, "<f4") for f in names])
    for f in names:
        out[f] = data[f]
    if edit:
        edit(out)
    plyfile.PlyData([plyfile.PlyElement.describe(out, "vertex")]).write(str(path))
    return path


def test_missing_file(tmp_path):
    with pytest.raises(SceneFormatError, match=r"nope\.ply: file not found"):
        load_scene(tmp_path / "nope.ply")


def test_unknown_extension(tmp_path):
    (tmp_path / "scene.obj").write_text("v 0 0 0\n")
    with pytest.raises(SceneFormatError, match=r"scene\.obj: unknown scene extension '\.obj'; supported: \.ply"):
        load_scene(tmp_path / "scene.obj")


def test_directory(tmp_path):
    (tmp_path / "d.ply").mkdir()
    with pytest.raises(SceneFormatError, match="not a regular file"):
        load_scene(tmp_path / "d.ply")


def test_not_a_ply(tmp_path):
    (tmp_path / "x.ply").write_bytes(b"\x00\x01garbage")
    with pytest.raises(SceneFormatError, match=r"x\.ply: not a PLY file"):
        load_scene(tmp_path / "x.ply")


def test_bad_ply_header(tmp_path):
    (tmp_path / "h.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty flot x\nend_header\n")
    with pytest.raises(SceneFormatError, match=r"h\.ply: invalid PLY file"):
        load_scene(tmp_path / "h.ply")


def test_truncated_real_ply(tmp_path):
    raw = BANANA.read_bytes()
    (tmp_path / "banana.ply").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(SceneFormatError, match=r"banana\.ply: truncated or corrupt PLY data .*early end-of-file"):
        load_scene(tmp_path / "banana.ply")


def test_trailing_bytes(tmp_path):
    path = _inria_ply(tmp_path / "t.ply")
    path.write_bytes(path.read_bytes() + b"\x00" * 7)
    with pytest.raises(SceneFormatError, match=r"t\.ply: file has \d+ bytes but its header describes \d+"):
        load_scene(path)


def test_missing_fields_are_named(tmp_path):
    path = _inria_ply(tmp_path / "m.ply", drop=("opacity", "rot_2"))
    with pytest.raises(SceneFormatError, match=r"m\.ply: .*lacks required .*field\(s\) opacity, rot_2"):
        load_scene(path)


def test_plain_point_cloud_ply(tmp_path):
    pts = np.zeros(4, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1")])
    plyfile.PlyData([plyfile.PlyElement.describe(pts, "vertex")]).write(str(tmp_path / "pc.ply"))
    with pytest.raises(SceneFormatError, match=r"pc\.ply: .*lacks required .*f_dc_0.*scale_0"):
        load_scene(tmp_path / "pc.ply")


def test_nan_value(tmp_path):
    def edit(a):
        a["y"][5] = np.nan

    path = _inria_ply(tmp_path / "nan.ply", edit=edit)
    with pytest.raises(SceneFormatError, match=r"nan\.ply: 1 of 20 splat\(s\) have NaN/Inf in 'means' \(first at index 5\)"):
        load_scene(path)


def test_inf_log_scale(tmp_path):
    def edit(a):
        a["scale_1"][2] = np.inf

    with pytest.raises(SceneFormatError, match="NaN/Inf in 'scales'"):
        load_scene(_inria_ply(tmp_path / "inf.ply", edit=edit))


def test_inf_opacity_logit(tmp_path):
    def edit(a):
        a["opacity"][4] = -np.inf

    with pytest.raises(SceneFormatError, match="NaN/Inf in 'opacities'"):
        load_scene(_inria_ply(tmp_path / "o.ply", edit=edit))


def test_zero_quaternion(tmp_path):
    def edit(a):
        for i in range(4):
            a[f"rot_{i}"][[3, 7]] = 0.0

    path = _inria_ply(tmp_path / "zq.ply", edit=edit)
    with pytest.raises(SceneFormatError, match=r"zq\.ply: 2 of 20 splat\(s\) have a zero quaternion .*first at index 3.*drop_invalid=True"):
        load_scene(path)


def test_drop_invalid_counts(tmp_path):
    def edit(a):
        a["x"][0] = np.nan
        for i in range(4):
            a[f"rot_{i}"][1] = 0.0

    s = load_scene(_inria_ply(tmp_path / "d.ply", edit=edit), drop_invalid=True, filter_floaters=False)
    assert len(s) == 18
    assert s.info["invalid_dropped"]["total"] == 2


def test_non_positive_scale_in_splat_file(tmp_path):
    s = random_splats(10, seed=2)
    write_splat(s, tmp_path / "s.splat")
    raw = bytearray((tmp_path / "s.splat").read_bytes())
    raw[32 * 4 + 12 : 32 * 4 + 16] = np.float32(-0.01).tobytes()  # splat 4, scale x
    (tmp_path / "s.splat").write_bytes(bytes(raw))
    with pytest.raises(SceneFormatError, match=r"s\.splat: 1 of 10 splat\(s\) have non-positive scales .*index 4"):
        load_scene(tmp_path / "s.splat")


def test_truncated_splat(tmp_path):
    write_splat(random_splats(10, seed=3), tmp_path / "t.splat")
    (tmp_path / "t.splat").write_bytes((tmp_path / "t.splat").read_bytes()[:-5])
    with pytest.raises(SceneFormatError, match=r"t\.splat: \.splat size 315 bytes is not a multiple of 32"):
        load_scene(tmp_path / "t.splat")


def test_empty_splat(tmp_path):
    (tmp_path / "e.splat").write_bytes(b"")
    with pytest.raises(SceneFormatError, match="empty"):
        load_scene(tmp_path / "e.splat")


def test_compressed_missing_chunk_field(tmp_path):
    write_compressed_ply(random_splats(300, seed=4), tmp_path / "c.ply")
    ply = plyfile.PlyData.read(str(tmp_path / "c.ply"), mmap=False)
    chunk = ply["chunk"].data
    names = [f for f in chunk.dtype.names if f != "max_scale_y"]
    cut = np.empty(len(chunk), dtype=[(f, "<f4") for f in names])
    for f in names:
        cut[f] = chunk[f]
    plyfile.PlyData([plyfile.PlyElement.describe(cut, "chunk"), ply["vertex"]]).write(str(tmp_path / "c.ply"))
    with pytest.raises(SceneFormatError, match=r"c\.ply: compressed PLY 'chunk' element lacks field\(s\) max_scale_y"):
        load_scene(tmp_path / "c.ply")


def test_compressed_too_few_chunks(tmp_path):
    write_compressed_ply(random_splats(600, seed=5), tmp_path / "c.ply")
    ply = plyfile.PlyData.read(str(tmp_path / "c.ply"), mmap=False)
    short = plyfile.PlyElement.describe(ply["chunk"].data[:2], "chunk")
    plyfile.PlyData([short, ply["vertex"]]).write(str(tmp_path / "c.ply"))
    with pytest.raises(SceneFormatError, match="2 chunk rows but 600 splats need 3"):
        load_scene(tmp_path / "c.ply")


def test_spz_not_gzip(tmp_path):
    (tmp_path / "a.spz").write_bytes(b"PSGN not gzipped")
    with pytest.raises(SceneFormatError, match=r"a\.spz: cannot decompress .*neither gzip data .* nor starts with 'NGSP'"):
        load_scene(tmp_path / "a.spz")


def test_spz_v4_truncated_header(tmp_path):
    (tmp_path / "a.spz").write_bytes(b"NGSP not zstd")
    with pytest.raises(SceneFormatError, match=r"a\.spz: \.spz file is 13 bytes, shorter than the 32-byte NGSP header"):
        load_scene(tmp_path / "a.spz")


def test_spz_truncated_gzip(tmp_path):
    write_spz(random_splats(50, seed=6), tmp_path / "a.spz")
    (tmp_path / "a.spz").write_bytes((tmp_path / "a.spz").read_bytes()[:-40])
    with pytest.raises(SceneFormatError, match=r"a\.spz: .*(truncated|corrupt)"):
        load_scene(tmp_path / "a.spz")


def _spz_raw(path: Path, **kw) -> Path:
    s = random_splats(20, seed=7)
    write_spz_raw(path, means_rub=s.means, quats_rub_wxyz=s.quats, log_scales=np.log(s.scales), opacities=s.opacities, f_dc=np.zeros((20, 3)), sh_rub=None, **kw)
    return path


def test_spz_bad_magic(tmp_path):
    with pytest.raises(SceneFormatError, match="bad .spz magic 0x12345678"):
        load_scene(_spz_raw(tmp_path / "m.spz", header_override={"magic": 0x12345678}))


def test_spz_unsupported_version(tmp_path):
    with pytest.raises(SceneFormatError, match=r"\.spz version 1 is not supported \(supported: 2 and 3 \(gzip\) and 4 \(NGSP header \+ zstd streams\)\)"):
        load_scene(_spz_raw(tmp_path / "v.spz", header_override={"version": 1}))


def test_spz_payload_short(tmp_path):
    with pytest.raises(SceneFormatError, match=r"p\.spz: \.spz payload \(header: 20 points, SH degree 0, version 2\) ends after 377 of the 380 bytes its header describes; the file is truncated"):
        load_scene(_spz_raw(tmp_path / "p.spz", payload_trim=3))


def test_spz_empty_gzip(tmp_path):
    (tmp_path / "e.spz").write_bytes(gzip.compress(b"NGSP"))
    with pytest.raises(SceneFormatError, match="shorter than the 16-byte header"):
        load_scene(tmp_path / "e.spz")


def test_checkpoint_garbage(tmp_path):
    pytest.importorskip("torch")
    (tmp_path / "g.pt").write_bytes(b"this is not a torch file")
    with pytest.raises(SceneFormatError, match=r"g\.pt: cannot load as a torch checkpoint"):
        load_scene(tmp_path / "g.pt")


def test_checkpoint_missing_keys(tmp_path):
    torch = pytest.importorskip("torch")
    torch.save({"splats": {"means": torch.zeros(3, 3), "quats": torch.ones(3, 4)}}, tmp_path / "k.ckpt")
    with pytest.raises(SceneFormatError, match=r"k\.ckpt: gsplat checkpoint lacks key\(s\) scales, opacities, sh0"):
        load_scene(tmp_path / "k.ckpt")


def test_checkpoint_wrong_shape(tmp_path):
    torch = pytest.importorskip("torch")
    n = 4
    params = {"means": torch.zeros(n, 3), "quats": torch.ones(n, 4), "scales": torch.zeros(n, 5), "opacities": torch.zeros(n), "sh0": torch.zeros(n, 1, 3)}
    torch.save(params, tmp_path / "w.pt")
    with pytest.raises(SceneFormatError, match=r"wrong shapes: scales \(4, 5\)"):
        load_scene(tmp_path / "w.pt")


def test_checkpoint_not_a_dict(tmp_path):
    torch = pytest.importorskip("torch")
    torch.save(torch.zeros(3), tmp_path / "t.pt")
    with pytest.raises(SceneFormatError, match="holds no splat parameters"):
        load_scene(tmp_path / "t.pt")


def test_save_scene_rejects_other_extensions(tmp_path):
    with pytest.raises(SceneFormatError, match=r"writes INRIA \.ply or Niantic \.spz \(version 4\); got extension '\.splat'"):
        save_scene(random_splats(5), tmp_path / "x.splat")


def test_save_scene_rejects_bad_values(tmp_path):
    s = random_splats(5)
    s.means[2, 0] = np.nan
    with pytest.raises(SplatplanError, match="NaN/Inf in 'means'"):
        save_scene(s, tmp_path / "x.ply")
    assert not (tmp_path / "x.ply").exists()


def test_empty_scene(tmp_path):
    empty = plyfile.PlyElement.describe(np.zeros(0, dtype=[(f, "<f4") for f in ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")]), "vertex")
    plyfile.PlyData([empty]).write(str(tmp_path / "e.ply"))
    with pytest.raises(SceneFormatError, match=r"e\.ply: the file holds no splats"):
        load_scene(tmp_path / "e.ply")
    with pytest.raises(SplatplanError, match="no splats"):
        save_scene(random_splats(3).subset(np.zeros(3, dtype=bool)), tmp_path / "out.ply")


def test_save_scene_rejects_mixed_disks(tmp_path):
    s = random_splats(5)
    s.scales[1, 2] = 0.0
    with pytest.raises(SplatplanError, match="some \\(not all\\) splats have a zero third scale"):
        save_scene(s, tmp_path / "x.ply")


def test_save_scene_missing_directory(tmp_path):
    with pytest.raises(SceneFormatError, match="cannot write here"):
        save_scene(random_splats(5), tmp_path / "no" / "such" / "dir" / "x.ply")


def test_checkpoint_without_splats(tmp_path):
    torch = pytest.importorskip("torch")
    params = {"means": torch.zeros(0, 3), "quats": torch.zeros(0, 4), "scales": torch.zeros(0, 3), "opacities": torch.zeros(0), "sh0": torch.zeros(0, 1, 3), "shN": torch.zeros(0, 15, 3)}
    torch.save({"step": 0, "splats": params}, tmp_path / "empty.pt")
    with pytest.raises(SceneFormatError, match=r"empty\.pt: the checkpoint holds no splats \('means' has 0 rows\)"):
        load_scene(tmp_path / "empty.pt")


def test_checkpoint_without_torch_names_the_extra(tmp_path, monkeypatch):
    (tmp_path / "c.pt").write_bytes(b"PK\x03\x04 whatever")
    monkeypatch.setitem(sys.modules, "torch", None)  # import torch -> ImportError
    with pytest.raises(SplatplanError, match=r"c\.pt: reading a gsplat checkpoint needs PyTorch, which is not installed: pip install 'splatplan\[baselines\]'"):
        load_scene(tmp_path / "c.pt")


def test_checkpoint_zip_bomb(tmp_path):
    """A deflated zip entry claiming far more than it can hold is refused before torch sees it."""
    import zipfile

    with zipfile.ZipFile(tmp_path / "z.pt", "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("archive/data.pkl", b"\x80\x02}q\x00.")
        with z.open("archive/data/0", "w") as f:
            block = bytes(1 << 20)
            for _ in range(32):
                f.write(block)
    with pytest.raises(SceneFormatError, match=r"z\.pt: checkpoint entry 'archive/data/0' claims 33,554,432 bytes from [\d,]+ compressed .*decompression bomb"):
        load_scene(tmp_path / "z.pt")
