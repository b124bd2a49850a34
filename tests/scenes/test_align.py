"""Aligning captures: up axis, floor at z = 0, splats kept in order, the sidecar transform, bad input.

Synthetic y-down rooms (floor, walls, a far sky shell of huge splats) test the fit; the real
captures in ``<repo>/../shared/data/real`` are used when present (skipped otherwise).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes import Splats, load_scene, rotmat_to_quat
from splatplan.scenes.align import AlignConfig, align_scene, describe_frame, guess_up, oversized_splats
from splatplan.scenes.transforms import Y_DOWN_TO_Z_UP

REPO = Path(__file__).resolve().parents[2]
SHARED_REAL = REPO / ".." / "shared" / "data" / "real"
TRUCK = SHARED_REAL / "uav4geo_truck.splat"
BATHROOM = SHARED_REAL / "ARVR_Apartments_Toilet.compressed.ply"


def patch(rng, centre, u, v, n, size_u, size_v, std=0.03):
    """Flat splats (N,) on the rectangle centre + a u + b v, |a| < size_u/2, |b| < size_v/2, normal u x v."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    a = rng.uniform(-0.5, 0.5, (n, 1)) * size_u
    b = rng.uniform(-0.5, 0.5, (n, 1)) * size_v
    means = np.asarray(centre, float) + a * u + b * v + rng.normal(0, 0.003, (n, 1)) * np.cross(u, v)
    r = np.stack([u, v, np.cross(u, v)], axis=1)  # local x, y, z (normal) -> world
    quats = np.repeat(rotmat_to_quat(r)[None], n, axis=0)
    scales = np.tile([std, std, std * 0.05], (n, 1))
    return means, quats, scales


def room_y_down(seed=0, floor_y=0.4, shell=True) -> Splats:
    """A 3 x 3 m room, 2.5 m tall, in a y-down capture frame (floor at y = floor_y, ceiling above at
    floor_y - 2.5), no ceiling captured, a box on the floor and an optional sky shell at radius 40."""
    rng = np.random.default_rng(seed)
    ex, ey, ez = np.eye(3)
    parts = [
        patch(rng, (0, floor_y, 0), ex, ez, 6000, 3.0, 3.0),  # floor (normal -y: up)
        patch(rng, (1.5, floor_y - 1.25, 0), ey, ez, 2500, 2.5, 3.0),  # walls
        patch(rng, (-1.5, floor_y - 1.25, 0), ez, ey, 2500, 3.0, 2.5),
        patch(rng, (0, floor_y - 1.25, 1.5), ex, ey, 2500, 3.0, 2.5),
        patch(rng, (0.3, floor_y - 0.5, -0.4), ex, ez, 800, 0.6, 0.6),  # a table top
    ]
    means, quats, scales = (np.concatenate(x) for x in zip(*parts))
    if shell:
        d = rng.normal(size=(2000, 3))
        means = np.concatenate([means, 40 * d / np.linalg.norm(d, axis=1, keepdims=True)])
        quats = np.concatenate([quats, np.tile([1.0, 0, 0, 0], (2000, 1))])
        scales = np.concatenate([scales, np.full((2000, 3), 5.0)])
    n = len(means)
    return Splats(means, quats, scales, np.full(n, 0.9), rng.uniform(0, 1, (n, 3)))


def test_align_room_finds_up_and_puts_the_floor_at_zero():
    s = room_y_down(floor_y=0.4)
    dropped, dres = align_scene(s)  # by default the far sky shell (the last 2000 splats) is dropped
    assert dres.n_shell_dropped == 2000 and len(dropped) == len(s) - 2000
    np.testing.assert_allclose(dropped.means, s.means[:-2000].astype(np.float64) @ dres.transform[:3, :3].T + dres.transform[:3, 3], atol=1e-5)
    out, res = align_scene(s, AlignConfig(keep_shell=True))
    assert np.dot(res.up.up, [0, -1, 0]) > np.cos(np.radians(1.0))  # the capture's -y is up
    assert res.up.floor_height == pytest.approx(-0.4, abs=0.02)  # along up = -y
    assert len(out) == len(s) and res.n_cropped == 0
    # every splat kept, in order: x_out = T [x_in; 1]
    t = res.transform
    np.testing.assert_allclose(out.means, s.means.astype(np.float64) @ t[:3, :3].T + t[:3, 3], atol=1e-5)
    floor = slice(0, 6000)
    assert abs(float(np.median(out.means[floor, 2]))) < 0.02
    # orientations rotate with the scene: covariances follow R Sigma R^T
    r = t[:3, :3]
    np.testing.assert_allclose(out.covariances()[:50], r @ s.covariances()[:50] @ r.T, atol=1e-6)
    np.testing.assert_allclose(r, Y_DOWN_TO_Z_UP, atol=0.02)
    assert res.up.confidence > 0.3
    assert res.n_shell >= 2000  # the sky shell is reported, not fitted


def test_align_scale_rotate_translate_and_crop():
    s = room_y_down(shell=False)
    cfg = AlignConfig(scale=2.0, rotate_z=90.0, translate=(1.0, 0.0, 0.0))
    out, res = align_scene(s, cfg)
    np.testing.assert_allclose(out.scales, s.scales * 2.0, rtol=1e-6)
    assert res.scale == 2.0
    np.testing.assert_allclose(np.linalg.det(res.transform[:3, :3]), 8.0, rtol=1e-6)
    assert abs(float(np.median(out.means[:6000, 2]))) < 0.04  # floor still at z = 0 after scaling
    cropped, cres = align_scene(s, AlignConfig(crop=(-1.0, -1.0, -0.5, 1.0, 1.0, 3.0)))
    assert cres.n_cropped == len(s) - len(cropped) > 0
    assert np.all(np.abs(cropped.means[:, :2]) <= 1.0)


def test_given_up_axis_and_floor():
    s = room_y_down(floor_y=0.4, shell=False)
    out, res = align_scene(s, AlignConfig(up="-y"))
    assert abs(float(np.median(out.means[:6000, 2]))) < 0.02
    out, res = align_scene(s, AlignConfig(up="-y", floor="-0.4"))
    assert abs(float(np.median(out.means[:6000, 2]))) < 0.01
    out, res = align_scene(s, AlignConfig(up="-y", floor="none"))
    assert float(np.median(out.means[:6000, 2])) == pytest.approx(-0.4, abs=0.01)


def test_bad_alignments_raise():
    rng = np.random.default_rng(0)
    n = 3000
    blob = Splats(rng.normal(size=(n, 3)), np.tile([1.0, 0, 0, 0], (n, 1)), np.full((n, 3), 0.02), np.full(n, 0.9), np.zeros((n, 3)))
    with pytest.raises(SplatplanError, match="no plane to align to.*--up"):
        align_scene(blob)
    with pytest.raises(SplatplanError, match="below the floor"):
        align_scene(room_y_down(shell=False), AlignConfig(translate=(0.0, 0.0, -3.0)))
    for bad in (AlignConfig(scale=float("nan")), AlignConfig(up="up"), AlignConfig(floor="nan"), AlignConfig(crop=(0, 0, 0, 0, 1, 1))):
        with pytest.raises(SplatplanError):
            align_scene(blob, bad)


def test_describe_frame_reports_shell_transparency_and_absurd_splats():
    s = room_y_down()
    d = describe_frame(s)
    assert d["up_guess"]["up_axis"] == "-y"
    assert d["shell"]["count"] >= 2000 and d["shell"]["radius_median"] > 30
    assert d["absurd_splats"] >= 2000 and oversized_splats(s)[-2000:].all()
    assert "looks metric" in d["scale_note"]
    s.opacities[:] = 0.04
    assert any("nearly transparent" in w for w in describe_frame(s)["warnings"])


def test_cli_scene_align_writes_scene_and_sidecar(tmp_path, capsys):
    from splatplan.cli import main
    from splatplan.scenes import save_scene

    src = tmp_path / "room.ply"
    save_scene(room_y_down(shell=False), src)
    out = tmp_path / "aligned.ply"
    assert main(["scene", "align", str(src), "--out", str(out), "--translate", "-0.5,0,0"]) == 0
    text = capsys.readouterr().out
    assert "transform" in text and "every splat kept" in text
    side = json.loads((tmp_path / "aligned.align.json").read_text())
    assert side["up"]["up_axis"] == "-y" and side["options"]["translate"] == [-0.5, 0.0, 0.0]
    a = load_scene(out, filter_floaters=False)
    assert len(a) == len(load_scene(src, filter_floaters=False))
    assert main(["info", str(out)]) == 0
    info = capsys.readouterr().out
    assert "aligned by `splatplan scene align`" in info and "z-up, floor at z = 0" in info and "robust bounds" in info
    assert main(["info", str(out), "--json"]) == 0  # the fit on the aligned file agrees with the record
    assert json.loads(capsys.readouterr().out)["up_guess"]["up_axis"] == "+z"
    for argv, needle in (
        (["scene", "align", str(src), "--out", str(tmp_path / "x.ply"), "--scale", "nan"], "scale"),
        (["scene", "align", str(src), "--out", str(tmp_path / "x.ply"), "--translate", "0,0,-5"], "below the floor"),
        (["scene", "align", str(src), "--out", str(tmp_path / "x.ply"), "--translate", "nan,0,0"], "--translate"),
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("splatplan: error:") and needle in err and err.count("\n") == 1, err
    assert not (tmp_path / "x.ply").exists()


def _floor_mode(out: Splats) -> float:
    """Height of the densest 1 cm layer of flat, horizontal splats in the lowest 30 cm (the floor)."""
    from splatplan.scenes.align import splat_normals

    n, flat = splat_normals(out)
    z = out.means[:, 2]
    sel = flat & (np.abs(n[:, 2]) > 0.9) & (z > -0.3) & (z < 0.3)
    h, e = np.histogram(z[sel], bins=60, range=(-0.3, 0.3), weights=out.opacities[sel])
    return float(0.5 * (e[np.argmax(h)] + e[np.argmax(h) + 1]))


@pytest.mark.skipif(not BATHROOM.exists(), reason=f"{BATHROOM} not present")
def test_real_bathroom_floor_at_zero():
    out, res = align_scene(load_scene(BATHROOM, filter_floaters=False))
    assert res.up.to_json()["up_axis"] == "-y"  # y-down capture, as its renders show
    assert abs(_floor_mode(out)) <= 0.02
    assert len(out) == res.n_in


@pytest.mark.skipif(not TRUCK.exists(), reason=f"{TRUCK} not present")
def test_real_truck_ground_at_zero():
    out, res = align_scene(load_scene(TRUCK, filter_floaters=False))
    assert res.up.to_json()["up_axis"] == "-y"
    assert abs(_floor_mode(out)) <= 0.02


def test_drop_floaters_removes_faint_isolated_splats_only():
    from splatplan.scenes.filters import isolated_mask

    s = room_y_down(shell=False)
    rng = np.random.default_rng(3)
    n = 60
    fl = np.c_[rng.uniform(-1, 1, n), rng.uniform(-1.5, -0.3, n) + 0.4, rng.uniform(-1, 1, n)]  # free space, y-down room
    op = np.r_[np.full(n // 2, 0.05), np.full(n // 2, 0.9)]  # half faint, half opaque
    both = Splats(np.r_[s.means, fl], np.r_[s.quats, np.tile([1.0, 0, 0, 0], (n, 1))], np.r_[s.scales, np.full((n, 3), 0.05)],
                  np.r_[s.opacities, op], np.r_[s.colors, np.zeros((n, 3))])  # fmt: skip
    iso = isolated_mask(both.means, both.opacities)
    assert iso[len(s) : len(s) + n // 2].mean() > 0.8 and not iso[len(s) + n // 2 :].any()
    assert iso[: len(s)].mean() < 0.01
    assert not isolated_mask(both.means, both.opacities, candidates=np.arange(len(both)) < len(s)).any()
    out, res = align_scene(both, AlignConfig(drop_floaters=True))
    assert res.n_floaters == len(both) - len(out) >= 0.8 * n // 2  # (align leaves the floor's splats out of the test)
    assert res.to_json()["n_floaters_dropped"] == res.n_floaters
