"""Alignment that knows when it does not know: object captures (a chair without its floor, a house
on a table disc, a tap on a wall inside a far shell, a standing person), in capture frames whose
convention holds (up within 25 degrees of ``up_hint``) or does not (up perpendicular to it).

The rule under test: ``up = auto`` finds the right up (within 10 degrees) or refuses with
:class:`AlignmentRefused`; it is never confidently wrong. The real captures in
``<repo>/../shared/data/real`` are checked the same way when present.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from splatplan.scenes import load_scene, save_scene
from splatplan.scenes.align import AlignConfig, AlignmentRefused, align_scene, guess_up
from splatplan.scenes.conventions import capture_convention, read_align_sidecar
from splatplan.scenes.filters import far_shell_mask

from .capture_shapes import chair, house_on_disc, in_capture_frame, person, tap_on_wall

REAL = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "real"
AXIS = {"-y": np.array([0.0, -1.0, 0.0]), "+z": np.array([0.0, 0.0, 1.0]), "+x": np.array([1.0, 0.0, 0.0])}


def _rot(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def capture_rotation(rng, world_up_to, max_tilt_deg=25.0):
    """x_capture = R x_world with R @ +z within ``max_tilt_deg`` of ``world_up_to`` (random yaw and tilt)."""
    target = np.asarray(world_up_to, float)
    base = _rot(np.cross([0, 0, 1.0], target), np.arccos(np.clip(target[2], -1, 1))) if abs(target[2]) < 1 - 1e-9 else (np.eye(3) if target[2] > 0 else np.diag([1.0, -1, -1]))
    yaw = _rot([0, 0, 1.0], rng.uniform(0, 2 * np.pi))
    tilt = _rot(rng.normal(size=3) * [1, 1, 0] + [1e-9, 0, 0], np.radians(rng.uniform(0, max_tilt_deg)))
    return base @ tilt @ yaw


def right_or_refused(s, truth, hint):
    """'right', or 'refused'; fails on a wrong up (more than 10 degrees from ``truth``)."""
    try:
        g = guess_up(s, AlignConfig(up_hint=hint))
    except AlignmentRefused as exc:
        assert "--up" in str(exc) or "--wall" in str(exc)
        return "refused"
    err = float(np.degrees(np.arccos(np.clip(g.up @ truth, -1, 1))))
    assert err < 10.0, f"confidently wrong: up {np.round(g.up, 3)} is {err:.0f} degrees from the truth {np.round(truth, 3)} (confidence {g.confidence:.2f})"
    return "right"


@pytest.mark.parametrize("name,build", [("chair", chair), ("chair, back apart from the legs", lambda: chair(rear_posts=False)), ("person", person)])
def test_no_floor_objects_are_refused_not_laid_on_their_side(name, build):
    """A chair (its back is a one-sided plane with the legs in its hull) and a person have no
    support plane: whatever the convention, auto refuses (or, never, lays them down)."""
    rng = np.random.default_rng(7)
    s0 = build()
    outcomes = []
    for hint, target in (("-y", "-y"), ("+z", "+z"), ("-y", "+x"), ("+z", "-y")):  # the convention holds, then not
        r = capture_rotation(rng, AXIS[target])
        outcomes.append(right_or_refused(in_capture_frame(s0, r), r @ [0, 0, 1.0], hint))
    assert "refused" in outcomes, outcomes


def test_house_on_a_table_disc_finds_the_disc_when_the_convention_holds():
    rng = np.random.default_rng(3)
    s0 = house_on_disc()
    for _ in range(3):
        r = capture_rotation(rng, AXIS["-y"])
        s = in_capture_frame(s0, r, (0.3, -1.0, 2.0))
        assert right_or_refused(s, r @ [0, 0, 1.0], "-y") == "right"
        out, res = align_scene(s)
        disc = out.means[: int(0.5 * len(out))]  # the disc's top comes first
        assert abs(float(np.median(disc[:, 2]))) < 0.01  # the table at z = 0
        assert res.up.plane.coverage > 0.9 and res.up.margin > 0.9
    r = capture_rotation(rng, AXIS["+x"])  # a file in another convention: refused, not laid on its side
    assert right_or_refused(in_capture_frame(s0, r), r @ [0, 0, 1.0], "-y") == "refused"


def test_tap_on_a_wall_refuses_auto_and_aligns_with_wall():
    r = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # z-up world -> y-down capture
    s = in_capture_frame(tap_on_wall(), r, (2.0, 0.5, -1.0))
    with pytest.raises(AlignmentRefused, match="--wall"):
        align_scene(s)
    out, res = align_scene(s, AlignConfig(wall="+y", floor="none"))
    assert res.n_shell_dropped == 10242 and len(out) == len(s) - 10242
    t = res.transform[:3, :3]
    np.testing.assert_allclose(t @ r @ [0, 0, 1.0], [0, 0, 1], atol=1e-3)  # up
    np.testing.assert_allclose(t @ r @ [1.0, 0, 0], [0, 1, 0], atol=1e-3)  # the wall's normal -> +y
    assert abs(float(np.median(out.means[:30000, 1]))) < 1e-3  # the wall at y = 0
    assert float(np.percentile(out.means[30000:, 1], 5)) > -1e-3  # the tap in front of it
    kept, kres = align_scene(s, AlignConfig(wall="+y", floor="none", keep_shell=True))
    assert kres.n_shell_dropped == 0 and len(kept) == len(s)


def test_far_shell_mask_finds_the_shell_and_nothing_in_a_room():
    s = tap_on_wall()
    mask = far_shell_mask(s.means)
    assert mask[-10242:].all() and not mask[:-10242].any()
    assert not far_shell_mask(tap_on_wall(shell=0).means).any()
    assert not far_shell_mask(house_on_disc().means).any()


def test_cli_align_png_sidecar_and_info(tmp_path, capsys):
    from splatplan.cli import main

    r = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    src = tmp_path / "house.ply"
    save_scene(in_capture_frame(house_on_disc(), r), src)
    out, png = tmp_path / "house_z.ply", tmp_path / "house_z.png"
    assert main(["scene", "align", str(src), "--out", str(out), "--png", str(png)]) == 0
    text = capsys.readouterr().out
    assert "support plane under" in text and png.stat().st_size > 10_000
    side = read_align_sidecar(out)
    assert side["floor_z"] == 0.0 and side["date"] and side["up"]["up_axis"] == "-y"
    assert capture_convention(out)[0] == "+z"
    assert main(["info", str(out)]) == 0
    assert "aligned by `splatplan scene align`" in capsys.readouterr().out
    assert main(["info", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["aligned"]["matches_file"] is True
    # a refusal: one line, exit 2, nothing written
    chair_in = tmp_path / "chair.ply"
    save_scene(in_capture_frame(chair(), r), chair_in)
    assert main(["scene", "align", str(chair_in), "--out", str(tmp_path / "c.ply"), "--png", str(tmp_path / "c.png")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("splatplan: error:") and "--up" in err and err.count("\n") == 1
    assert not (tmp_path / "c.ply").exists() and not (tmp_path / "c.png").exists() and not (tmp_path / "c.align.json").exists()
    # the wall of a tap, and info's shell advice works as written
    tap = tmp_path / "tap.ply"
    save_scene(in_capture_frame(tap_on_wall(), r), tap)
    assert main(["info", str(tap)]) == 0
    assert "`splatplan scene align IN --out OUT.ply` drops it" in capsys.readouterr().out
    assert main(["scene", "align", str(tap), "--out", str(tmp_path / "t.ply"), "--wall", "+x", "--floor", "none"]) == 0
    assert "background shell of 10,242 splats" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "t.ply")]) == 0
    assert "wall normal +x" in capsys.readouterr().out


def test_nerfstudio_header_sets_the_convention(tmp_path):
    p = tmp_path / "ns.ply"
    save_scene(house_on_disc(), p)  # z-up world
    raw = p.read_bytes()
    p.write_bytes(raw.replace(b"format binary_little_endian 1.0\n", b"format binary_little_endian 1.0\ncomment Vertical Axis: z\n", 1))
    assert capture_convention(p) == ("+z", "the .ply header says 'Vertical Axis: z' (nerfstudio)")
    assert len(load_scene(p, filter_floaters=False)) > 0


@pytest.mark.parametrize("name", ["equinor_banana_splat.ply", "playcanvas_biker.spz", "uav4geo_truck.splat", "ARVR_Apartments_Toilet.compressed.ply"])
def test_real_captures_right_or_refused(name):
    """All four real captures are y-down (up = -y, from their renders and side views): auto finds
    -y or refuses (the banana and the biker have no support plane); the rooms keep their up."""
    path = REAL / name
    if not path.exists():
        pytest.skip(f"{path} not present")
    s = load_scene(path, filter_floaters=False)
    outcome = right_or_refused(s, AXIS["-y"], "-y")
    if name.startswith(("uav4geo", "ARVR")):
        assert outcome == "right"
    assert not far_shell_mask(s.means).any()  # nothing of these captures is a background shell
