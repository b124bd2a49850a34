"""Round trips through every supported format: write (our writer or a test encoder), read back."""

from __future__ import annotations

import numpy as np
import plyfile
import pytest
from .scene_encoders import SH_PARITY_YZ, eval_sh, pack_rotation_wxyz, random_splats, write_compressed_ply, write_splat, write_spz, write_spz_raw

from splatplan.scenes import Splats, load_scene, save_scene
from splatplan.scenes.io_compressed_ply import unpack_rotation
from splatplan.scenes.io_spz import SH_FLIP_RUB_RDF


def same_rotation(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """|<qa, qb>| per row: 1 for the same rotation (q and -q are the same)."""
    return np.abs(np.sum(qa.astype(np.float64) * qb, axis=1))


def assert_same(a: Splats, b: Splats, *, pos=1e-6, quat=1e-6, rel_scale=1e-5, opac=1e-6, color=1e-5, sh=1e-5) -> None:
    assert len(a) == len(b)
    np.testing.assert_allclose(a.means, b.means, atol=pos)
    assert np.all(same_rotation(a.quats, b.quats) >= 1 - quat)
    np.testing.assert_allclose(a.scales, b.scales, rtol=rel_scale, atol=0)
    np.testing.assert_allclose(a.opacities, b.opacities, atol=opac)
    np.testing.assert_allclose(a.colors, b.colors, atol=color)
    if a.sh_rest is None:
        assert b.sh_rest is None
    else:
        np.testing.assert_allclose(a.sh_rest, b.sh_rest, atol=sh)


@pytest.mark.parametrize("k_sh", [0, 3, 15])
def test_inria_ply_roundtrip(tmp_path, k_sh):
    s = random_splats(500, k_sh=k_sh, seed=k_sh)
    save_scene(s, tmp_path / "scene.ply")
    back = load_scene(tmp_path / "scene.ply", filter_floaters=False)
    assert back.source_format == "inria"
    assert_same(s, back, quat=1e-6, rel_scale=1e-5)
    names = set(plyfile.PlyData.read(str(tmp_path / "scene.ply"))["vertex"].data.dtype.names)
    assert {"scale_2", "opacity", "rot_3", "f_dc_2"} <= names
    assert sum(n.startswith("f_rest_") for n in names) == 3 * k_sh


def test_2dgs_ply_roundtrip(tmp_path):
    s = random_splats(300, k_sh=3, is_2d=True, seed=3)
    save_scene(s, tmp_path / "disks.ply")
    names = set(plyfile.PlyData.read(str(tmp_path / "disks.ply"))["vertex"].data.dtype.names)
    assert "scale_2" not in names and {"scale_0", "scale_1"} <= names
    back = load_scene(tmp_path / "disks.ply", filter_floaters=False)
    assert back.source_format == "2dgs" and back.is_2d
    assert_same(s, back)


def test_ply_fields_read_by_name(tmp_path):
    """Shuffling the field order of a written file must not change what is read."""
    s = random_splats(200, k_sh=3, seed=4)
    save_scene(s, tmp_path / "a.ply")
    data = plyfile.PlyData.read(str(tmp_path / "a.ply"))["vertex"].data
    names = list(data.dtype.names)
    np.random.default_rng(0).shuffle(names)
    shuffled = np.empty(len(data), dtype=[(n, "<f4") for n in names])
    for n in names:
        shuffled[n] = data[n]
    plyfile.PlyData([plyfile.PlyElement.describe(shuffled, "vertex")]).write(str(tmp_path / "b.ply"))
    a, b = load_scene(tmp_path / "a.ply", filter_floaters=False), load_scene(tmp_path / "b.ply", filter_floaters=False)
    for name in ("means", "quats", "scales", "opacities", "colors", "sh_rest"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_save_scene_is_atomic(tmp_path, monkeypatch):
    """A failure in the middle of writing leaves the old file untouched and no temp file."""
    target = tmp_path / "scene.ply"
    save_scene(random_splats(50, seed=1), target)
    before = target.read_bytes()

    def broken_write(self, stream):
        stream.write(b"ply\nformat binary_little_endian 1.0\n")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(plyfile.PlyData, "write", broken_write)
    with pytest.raises(Exception, match="No space left"):
        save_scene(random_splats(80, seed=2), target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["scene.ply"]


def test_rotation_packing_roundtrip_each_largest_component():
    """The smallest-three decoder inverts our encoder, for every choice of largest component."""
    rng = np.random.default_rng(5)
    q = rng.normal(size=(4000, 4))
    for i in range(4):  # make component i the largest, with both signs
        q[i * 1000 : (i + 1) * 1000, i] = 3.0 * np.sign(rng.normal(size=1000))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    packed = pack_rotation_wxyz(q)
    assert set((packed >> np.uint32(30)).tolist()) == {0, 1, 2, 3}
    back = unpack_rotation(packed)
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), 1.0, atol=1e-12)
    assert np.all(same_rotation(q, back) > 1 - 2e-6)


@pytest.mark.parametrize("with_color_range", [True, False])
def test_compressed_ply_roundtrip(tmp_path, with_color_range):
    s = random_splats(700, k_sh=15, seed=6)  # 3 chunks, the last one partial
    write_compressed_ply(s, tmp_path / "c.ply", with_color_range=with_color_range)
    back = load_scene(tmp_path / "c.ply", filter_floaters=False)
    assert back.source_format == "compressed_ply"
    # quantisation: positions 1/2047 (x, z) or 1/1023 (y) of the chunk extent, log-scales the
    # same of the chunk log range, colours and opacity 1/255, SH 8/255
    extent, log_range = 4.0, np.log(1e-1 / 1e-3)
    assert_same(s, back, pos=extent / 1023 / 2 + 1e-6, quat=2e-6, rel_scale=np.expm1(log_range / 1023 / 2) + 1e-5, opac=0.5 / 255 + 1e-6, color=0.5 / 255 + 1e-6, sh=4 / 255 + 1e-6)


def test_splat_roundtrip(tmp_path):
    s = random_splats(400, seed=7)
    write_splat(s, tmp_path / "s.splat")
    back = load_scene(tmp_path / "s.splat", filter_floaters=False)
    assert back.source_format == "splat"
    # u8 quaternion components: |error| <= 1/256 each before normalising
    assert_same(s, back, quat=2e-4, rel_scale=1e-6, opac=0.5 / 255 + 1e-6, color=0.5 / 255 + 1e-6)


#: colour step of spz: one u8 step of f_dc (1 / (0.15 * 255)) times C0
SH_C0_OVER_SPZ = 0.28209479177387814 / (0.15 * 255)


@pytest.mark.parametrize("version", [2, 3])
def test_spz_roundtrip(tmp_path, version):
    s = random_splats(400, k_sh=15, seed=8)
    write_spz(s, tmp_path / "s.spz", version=version)
    back = load_scene(tmp_path / "s.spz", filter_floaters=False)
    assert back.source_format == "spz"
    # 12 fractional bits; log-scale step 1/16; v3 quaternions 9 bits + sign per component; v2
    # stores x, y, z in 8 bits and derives w, which is coarse (up to ~10 degrees) when w ~ 0
    quat_tol = 5e-3 if version == 2 else 2e-5
    assert_same(s, back, pos=0.5 / 4096 + 1e-6, quat=quat_tol, rel_scale=np.expm1(1 / 32) + 1e-5, opac=0.5 / 255 + 1e-6, color=0.5 * SH_C0_OVER_SPZ + 1e-6, sh=0.5 / 128 + 1e-6)


def test_spz_converts_rub_to_rdf(tmp_path):
    """Positions, covariances and SH of a RUB file come out mirrored by F = diag(1, -1, -1)."""
    rng = np.random.default_rng(9)
    n = 200
    means = rng.uniform(-1, 1, size=(n, 3))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    log_s = rng.uniform(-6, -2, size=(n, 3))
    sh = rng.uniform(-0.9, 0.9, size=(n, 15, 3))
    write_spz_raw(tmp_path / "r.spz", means_rub=means, quats_rub_wxyz=q, log_scales=log_s, opacities=np.full(n, 0.5), f_dc=np.zeros((n, 3)), sh_rub=sh, version=3)
    s = load_scene(tmp_path / "r.spz", filter_floaters=False)
    f = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(s.means, means @ f, atol=1e-3)
    ref = Splats(means=means, quats=q, scales=np.exp(np.round((log_s + 10) * 16) / 16 - 10), opacities=np.full(n, 0.5), colors=np.zeros((n, 3)))
    np.testing.assert_allclose(s.covariances(), f @ ref.covariances() @ f, atol=5e-3 * ref.covariances().max())
    # SH: the colour seen from direction F d in RDF equals the colour seen from d in RUB
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sh_q = (np.round(sh * 128 + 128) - 128) / 128
    np.testing.assert_allclose(eval_sh(s.sh_rest.astype(np.float64), d @ f), eval_sh(sh_q, d), atol=1e-5)
    np.testing.assert_array_equal(SH_FLIP_RUB_RDF[:15], SH_PARITY_YZ)


def _gsplat_params(s: Splats) -> dict:
    torch = pytest.importorskip("torch")
    k = 0 if s.sh_rest is None else s.sh_rest.shape[1]
    o = np.clip(s.opacities.astype(np.float64), 1e-6, 1 - 1e-6)
    return {
        "means": torch.tensor(s.means),
        "quats": torch.tensor(s.quats * 2.0),  # not normalised, as in training
        "scales": torch.tensor(np.log(s.scales)),
        "opacities": torch.tensor(np.log(o / (1 - o)), dtype=torch.float32),
        "sh0": torch.tensor((s.colors[:, None, :] - 0.5) / 0.28209479177387814),
        "shN": torch.tensor(s.sh_rest) if k else torch.zeros(len(s), 0, 3),
    }


@pytest.mark.parametrize("nested", [True, False])
def test_gsplat_checkpoint_roundtrip(tmp_path, nested):
    torch = pytest.importorskip("torch")
    s = random_splats(300, k_sh=8, seed=10)
    params = _gsplat_params(s)
    torch.save({"step": 29999, "splats": params} if nested else params, tmp_path / "ckpt_29999.pt")
    back = load_scene(tmp_path / "ckpt_29999.pt", filter_floaters=False)
    assert back.source_format == "gsplat_ckpt"
    assert_same(s, back, rel_scale=1e-5, opac=1e-6, color=1e-5)


def test_gsplat_checkpoint_without_higher_sh(tmp_path):
    torch = pytest.importorskip("torch")
    s = random_splats(50, seed=11)
    torch.save({"splats": _gsplat_params(s)}, tmp_path / "c.ckpt")
    back = load_scene(tmp_path / "c.ckpt", filter_floaters=False)
    assert back.sh_rest is None
    assert_same(s, back)


@pytest.mark.parametrize("layout", ["ascii", "big_endian", "float64_and_extra_fields"])
def test_ply_layouts_read_like_the_float32_file(tmp_path, layout):
    """Text, big-endian and mixed-type PLYs (fast matrix path or per-field path) give the same scene."""
    s = random_splats(150, k_sh=3, seed=12)
    save_scene(s, tmp_path / "a.ply")
    data = plyfile.PlyData.read(str(tmp_path / "a.ply"))["vertex"].data
    if layout == "float64_and_extra_fields":
        wide = np.empty(len(data), dtype=[(n, "<f8" if n.startswith("f_rest") else "<f4") for n in data.dtype.names] + [("label", "u1")])
        for n in data.dtype.names:
            wide[n] = data[n]
        wide["label"] = 7
        plyfile.PlyData([plyfile.PlyElement.describe(wide, "vertex")]).write(str(tmp_path / "b.ply"))
    else:
        el = plyfile.PlyElement.describe(np.array(data), "vertex")
        plyfile.PlyData([el], text=layout == "ascii", byte_order=">" if layout == "big_endian" else "<").write(str(tmp_path / "b.ply"))
    a, b = load_scene(tmp_path / "a.ply", filter_floaters=False), load_scene(tmp_path / "b.ply", filter_floaters=False)
    for name in ("means", "quats", "scales", "opacities", "colors", "sh_rest"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-6, atol=1e-7)
