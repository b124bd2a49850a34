"""Results that carry their frame: plan / mpc record the robot, base pose, metric settings and scene;
view, check and mpc --plan reuse them and warn when flags differ; clearances in metres; the planning
box of a ground robot grows by its footprint."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from splatplan.cli import main
from splatplan.cli._results import fill_robot, read_frame
from splatplan.planners.clearance import densify_by_motion
from splatplan.robots import load_robot
from splatplan.scenes.load import load_scene, save_scene

from .planners.scenes import make_scene

#: a wall across the middle and four corner posts (scene units, z up)
ROOM = [((-0.01, -0.25, 0.0), (0.01, 0.12, 0.12))] + [((x - 0.01, y - 0.01, 0.0), (x + 0.01, y + 0.01, 0.12)) for x in (-0.3, 0.3) for y in (-0.3, 0.3)]
#: a block where a Panda at the origin stands, and a small post 0.7 m in front of a Panda based at x = 2
ARM = [((-0.15, -0.15, 0.2), (0.15, 0.15, 0.5)), ((2.68, -0.02, 0.0), (2.72, 0.02, 0.1))]
#: a chair without a floor: four legs, a seat, a back (an object capture)
CHAIR = [((x - 0.02, y - 0.02, 0.0), (x + 0.02, y + 0.02, 0.45)) for x in (-0.2, 0.2) for y in (-0.2, 0.2)]
CHAIR += [((-0.22, -0.22, 0.43), (0.22, 0.22, 0.47)), ((-0.22, 0.18, 0.47), (0.22, 0.22, 0.9))]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    d = tmp_path_factory.mktemp("results")
    for name, boxes, spacing in (("room", ROOM, 0.012), ("arm", ARM, 0.02), ("chair", CHAIR, 0.02)):
        save_scene(make_scene(boxes, spacing=spacing), d / f"{name}.ply")
    return d


def _err_lines(err: str, head: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith(head)]


def test_plan_records_frame_and_clearance_in_metres(scenes, tmp_path, capsys):
    out = tmp_path / "p.json"
    code = main(["plan", str(scenes / "room.ply"), "--start", "-0.15,0,0.06", "--goal", "0.15,-0.05,0.06", "--planar", "--n-sigma", "0",
                 "--out", str(out), "--device", "cpu"])  # fmt: skip
    cap = capsys.readouterr()
    assert code == 0, cap.err
    doc = json.loads(out.read_text())
    fr = doc["frame"]
    assert fr["robot"] == "sphere:0.015" and fr["base_pose"] is None and fr["metric"]["n_sigma"] == 0.0
    assert fr["scene"]["path"] == str(scenes / "room.ply") and len(fr["scene"]["sha256"]) == 64
    assert "clearance" in cap.out and " cm " in cap.out
    # at n_sigma 0 the estimate of a sphere is exact: the smallest distance from the densified path to a splat mean, less the radius
    robot = load_robot("sphere:0.015")
    q = densify_by_motion(robot, np.asarray(doc["path"]), doc["clearance"]["step_m"])
    means = load_scene(scenes / "room.ply").means.astype(np.float64)
    true = min(float(np.sqrt(((means - p) ** 2).sum(axis=1)).min()) for p in q) - 0.015
    assert doc["clearance"]["n_samples"] == len(q) and not doc["clearance"]["at_least"]
    assert doc["clearance_m"] == pytest.approx(true, abs=2e-5)
    assert 0 < doc["clearance_m"] < 0.1


def test_check_and_view_use_the_recorded_base_pose(scenes, tmp_path, capsys):
    """A Panda planned at x = 2 (no --start: its home); check --plan without --base-pose checks it
    there (free), with another base pose it warns and finds the block."""
    out = tmp_path / "arm.json"
    home = load_robot("panda").q_default
    goal = ",".join(f"{v:g}" for v in home + np.r_[0.3, np.zeros(6)])
    code = main(["plan", str(scenes / "arm.ply"), "--robot", "panda", "--goal", goal, "--base-pose", "2,0,0", "--out", str(out),
                 "--time-limit", "60", "--device", "cpu"])  # fmt: skip
    cap = capsys.readouterr()
    assert code == 0, cap.err
    assert any("home configuration" in line for line in _err_lines(cap.err, "note:"))
    doc = json.loads(out.read_text())
    assert doc["frame"]["robot"] == "panda" and doc["frame"]["base_pose"] == [2, 0, 0, 1, 0, 0, 0]
    np.testing.assert_allclose(doc["path"][0], home)

    npz = tmp_path / "c.npz"
    assert main(["check", str(scenes / "arm.ply"), "--plan", str(out), "--out", str(npz), "--device", "cpu"]) == 0
    cap = capsys.readouterr()
    assert " 0 in collision with the scene" in cap.out and "cm" in cap.out
    assert any("base pose 2,0,0" in line for line in _err_lines(cap.err, "note:")) and not _err_lines(cap.err, "warning:")
    with np.load(npz) as z:
        assert z["clearance_m"].shape == z["min_s2"].shape and np.all(z["config_clearance_m"] > 0)

    assert main(["check", str(scenes / "arm.ply"), "--plan", str(out), "--base-pose", "0,0,0", "--device", "cpu"]) == 0
    cap = capsys.readouterr()
    warns = _err_lines(cap.err, "warning:")
    assert len(warns) == 1 and "--base-pose 0,0,0 differs" in warns[0] and "2,0,0" in warns[0]
    assert " 0 in collision with the scene" not in cap.out

    # view --plan: the recorded robot and base pose unless given (the viewer's argument filling, without a browser)
    ns = argparse.Namespace(robot=None, base_pose=None)
    fill_robot(ns, read_frame(doc, "--plan arm.json"))
    assert ns.robot == "panda" and ns.base_pose == "2,0,0"
    ns = argparse.Namespace(robot="panda", base_pose="1,0,0")
    fill_robot(ns, read_frame(doc, "--plan arm.json"))
    cap = capsys.readouterr()
    assert ns.base_pose == "1,0,0" and len(_err_lines(cap.err, "warning:")) == 1

    # another scene file: one warning naming both hashes
    other = tmp_path / "other.ply"
    save_scene(make_scene(ARM[1:], spacing=0.02), other)
    assert main(["check", str(other), "--plan", str(out), "--device", "cpu"]) == 0
    warns = _err_lines(capsys.readouterr().err, "warning:")
    assert len(warns) == 1 and "is not the scene" in warns[0] and "sha256" in warns[0]


def test_old_result_files_still_load(scenes, tmp_path, capsys):
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"success": True, "robot": "sphere", "path": [[-0.15, 0, 0.06], [-0.14, 0, 0.06]]}))
    assert read_frame(json.loads(old.read_text()), "x") is None
    assert main(["check", str(scenes / "room.ply"), "--plan", str(old), "--device", "cpu"]) == 2
    assert "records no robot" in capsys.readouterr().err
    assert main(["check", str(scenes / "room.ply"), "--plan", str(old), "--robot", "sphere:0.015", "--device", "cpu"]) == 0
    cap = capsys.readouterr()
    assert "2 configurations" in cap.out and not _err_lines(cap.err, "warning:")


def test_mpc_go2_around_an_object_and_its_box(scenes, tmp_path, capsys):
    chair = str(scenes / "chair.ply")
    out = tmp_path / "run"
    code = main(["mpc", "--robot", "go2", "--scene", chair, "--start", "-0.9,0.05,0", "--goal", "0.9,0.05", "--out", str(out), "--device", "cpu"])
    cap = capsys.readouterr()
    assert code in (0, 1) and "outside" not in cap.err, cap.err
    doc = json.loads((out / "result.json").read_text())
    assert doc["frame"]["robot"] == "go2" and doc["frame"]["scene"]["path"] == chair and "n_sigma" in doc["frame"]["metric"]

    code = main(["mpc", "--robot", "go2", "--scene", chair, "--start", "-0.9,0.05,0", "--goal", "3,0.05", "--out", str(tmp_path / "far")])
    err = capsys.readouterr().err
    assert code == 2 and "planning box" in err and "outside the scene" in err and "--box" in err and err.count("\n") == 1
    code = main(["mpc", "--robot", "go2", "--scene", chair, "--start", "-0.9,0.05,0", "--goal", "3,0.05", "--box", "-1,-1", "1,1", "--out", str(tmp_path / "far")])
    err = capsys.readouterr().err
    assert code == 2 and "the given box" in err
    code = main(["mpc", "--robot", "panda", "--goal-pose", "0.5,0,0.3,1,0,0,0", "--box", "-1,-1", "1,1", "--out", str(tmp_path / "arm")])
    assert code == 2 and "--box is for --robot go2" in capsys.readouterr().err


def test_terrain_only_where_a_floor_was_found(scenes):
    """An object capture (a chair, no floor): the ends of its legs stay obstacles; a floor under it
    makes them terrain as before."""
    from splatplan.scenes.terrain import TerrainConfig, remove_terrain

    chair = load_scene(scenes / "chair.ply")
    out, rep = remove_terrain(chair, TerrainConfig(floor_z=0.0))
    assert not rep.floor_found and rep.n_terrain == 0 and len(out) == len(chair) and "no floor" in rep.summary()
    out, rep = remove_terrain(chair, TerrainConfig(floor_z=0.0, min_floor_coverage=0.0))
    assert rep.floor_found and rep.n_terrain > 0
    on_floor = make_scene(CHAIR + [((-1.0, -1.0, -0.01), (1.0, 1.0, 0.0))], spacing=0.02)
    out, rep = remove_terrain(on_floor, TerrainConfig(floor_z=0.0))
    assert rep.floor_found and rep.n_terrain > 0
