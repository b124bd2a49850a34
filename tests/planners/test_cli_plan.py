"""`splatplan plan`: leading-minus vectors, --box, the printed settings, exit codes 0 / 1 / 2 and
no overwrite of an existing --out on failure."""

from __future__ import annotations

import json

import pytest

from splatplan.cli import main
from splatplan.scenes.load import save_scene

from .scenes import make_scene

#: a wall across the middle and four corner posts that give the scene its extent
ROOM = [((-0.01, -0.25, 0.0), (0.01, 0.12, 0.12))] + [((x - 0.01, y - 0.01, 0.0), (x + 0.01, y + 0.01, 0.12)) for x in (-0.3, 0.3) for y in (-0.3, 0.3)]
#: ... plus a closed box around (0.2, 0, 0.06): a goal inside it cannot be reached
SEALED = ROOM + [((0.14, -0.06, 0.0), (0.26, 0.06, 0.12))]


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    p = tmp_path_factory.mktemp("plan") / "room.ply"
    save_scene(make_scene(ROOM), p)
    return p


@pytest.fixture(scope="module")
def sealed(tmp_path_factory):
    p = tmp_path_factory.mktemp("plan") / "sealed.ply"
    save_scene(make_scene(SEALED, spacing=0.008), p)
    return p


def test_leading_minus_and_planar(room, tmp_path, capsys):
    out = tmp_path / "p.json"
    code = main(["plan", str(room), "--start", "-0.15,0,0.06", "--goal", "0.15,-0.05,0.06", "--planar", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    first = captured.out.splitlines()[0]
    assert first.startswith("plan sphere:0.015") and "stride* " in first and "time limit 10 s" in first
    doc = json.loads(out.read_text())
    assert doc["success"] and doc["path"][0] == [-0.15, 0.0, 0.06] and doc["path"][-1] == [0.15, -0.05, 0.06]
    assert all(abs(p[2] - 0.06) < 1e-12 for p in doc["path"])  # --planar holds z
    assert max(p[1] for p in doc["path"]) > 0.12  # around the wall's open end
    assert doc["settings"]["box_lo"][2] == doc["settings"]["box_hi"][2] == 0.06


def test_box_with_negative_corners(room, tmp_path, capsys):
    out = tmp_path / "p.json"
    code = main(["plan", str(room), "--start", "-0.15,0,0.06", "--goal", "0.15,0,0.06", "--box", "-0.25,-0.3,0.06", "0.25,0.3,0.06",
                 "--rrt-stride", "0.02", "--time-limit", "20", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    doc = json.loads(out.read_text())
    assert doc["settings"]["box_lo"] == [-0.25, -0.3, 0.06] and doc["settings"]["box_hi"] == [0.25, 0.3, 0.06]
    assert doc["settings"]["stride"] == 0.02 and doc["settings"]["time_limit_s"] == 20.0
    assert "box" not in doc["settings"]["derived"] and "stride" not in doc["settings"]["derived"]


def test_no_path_exits_1_and_keeps_existing_out(sealed, tmp_path, capsys):
    out = tmp_path / "p.json"
    out.write_text('{"keep": true}\n')
    args = ["plan", str(sealed), "--start", "-0.15,0,0.06", "--goal", "0.2,0,0.06", "--planar", "--time-limit", "0.3", "--out", str(out)]
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("splatplan: no path found within 0.3 s (") and "kept the existing" in err[0]
    assert json.loads(out.read_text()) == {"keep": True}
    assert main(args + ["--force"]) == 1
    doc = json.loads(out.read_text())
    assert doc["success"] is False and doc["path"] == [] and doc["length"] is None


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--start", "0,0", "--goal", "0.1,0,0.06"], "3 dofs"),
        (["--start", "-0.15,0,0.06", "--goal", "0.15,0,9"], "outside the scene bounds"),
        (["--start", "-0.15,0,0.06", "--goal", "0.15,0,0.06", "--robot", "panda"], "7 dofs"),
        (["--start", "-0.15,x,0.06", "--goal", "0.15,0,0.06"], "comma-separated numbers"),
    ],
)
def test_bad_input_exits_2(room, tmp_path, capsys, extra, words):
    out = tmp_path / "p.json"
    assert main(["plan", str(room), *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("splatplan: error:") and words in err[0], err
    assert not out.exists()


def test_planner_choice_and_time_split(room, tmp_path, capsys):
    out = tmp_path / "p.json"
    code = main(["plan", str(room), "--start", "-0.15,0,0.06", "--goal", "0.15,-0.05,0.06", "--planar", "--planner", "rrtconnect", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    lines = captured.out.splitlines()
    assert ", rrtconnect, " in lines[0]
    assert lines[-1].startswith("time split: sampling ") and "collision" in lines[-1] and "refine" in lines[-1]
    doc = json.loads(out.read_text())
    assert doc["planner"] == "rrtconnect" and doc["success"]
    assert sum(doc["time_split"].values()) <= doc["time_s"] + 1e-6
    assert main(["plan", str(room), "--start", "-0.15,0,0.06", "--goal", "0.15,-0.05,0.06", "--out", str(out)]) == 0
    assert ", rrt, " in capsys.readouterr().out.splitlines()[0]  # auto: a point robot keeps the RRT


def test_bad_planner_name_exits_2(room, tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["plan", str(room), "--start", "-0.15,0,0.06", "--goal", "0.15,0,0.06", "--planner", "prm", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("splatplan: error: unknown planner 'prm'"), err
    assert not out.exists()
