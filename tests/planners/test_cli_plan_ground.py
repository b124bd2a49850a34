"""`splatplan plan` asks the robot what it is: a planar robot loaded from a URDF that walks on
terrain (``--robot PATH.urdf:walking``) gets the terrain handling of the built-in go2 (the floor's
splats are ground, not obstacles); the same URDF as a planar base that does not walk does not."""

from __future__ import annotations

import json

import numpy as np
import pytest

from splatplan.cli import main
from splatplan.scenes import Splats
from splatplan.scenes.load import save_scene

from ..robots.ground_robot import write_ground_robot


@pytest.fixture(scope="module")
def floor(tmp_path_factory):
    """An open 4 x 4 m floor at z = 0.01 (flat splats, 4 cm stds) and two posts at its far corners."""
    rng = np.random.default_rng(0)
    n_floor, n_post = 6000, 400
    fl = np.c_[rng.uniform(-2, 2, (n_floor, 2)), 0.01 + rng.normal(0, 0.003, n_floor)]
    posts = np.c_[rng.uniform(-0.05, 0.05, (n_post, 2)) + rng.choice([-1.9, 1.9], (n_post, 2)), rng.uniform(0.0, 0.5, n_post)]
    means = np.concatenate([fl, posts])
    scales = np.concatenate([np.tile([0.04, 0.04, 0.002], (n_floor, 1)), np.full((n_post, 3), 0.02)])
    n = len(means)
    p = tmp_path_factory.mktemp("ground") / "floor.ply"
    save_scene(Splats(means, np.tile([1.0, 0, 0, 0], (n, 1)), scales, np.full(n, 0.9), np.full((n, 3), 0.5)), p)
    return p


def _plan(scene, robot: str, out, capsys) -> tuple[int, str, str]:
    code = main(["plan", str(scene), "--robot", robot, "--start", "-0.6,0,0", "--goal", "0.6,0,0", "--time-limit", "60", "--out", str(out), "--force"])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _terrain_notes(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("note: terrain:")]


def test_a_walking_urdf_gets_go2s_terrain_handling(floor, tmp_path, capsys):
    urdf = write_ground_robot(tmp_path / "crawler")
    code, out, err = _plan(floor, f"{urdf}:walking", tmp_path / "walker.json", capsys)
    assert code == 0, err
    walker_notes = _terrain_notes(err)
    assert len(walker_notes) == 1, err
    doc = json.loads((tmp_path / "walker.json").read_text())
    assert doc["success"] and doc["joint_names"] == ["x", "y", "yaw"]

    code, out, err = _plan(floor, "go2", tmp_path / "go2.json", capsys)
    assert code == 0, err
    assert _terrain_notes(err) == walker_notes  # the same floor splats removed, the same way

    # the same URDF as a planar base that does not walk: its body sits in the floor's splats
    code, out, err = _plan(floor, f"{urdf}:planar", tmp_path / "planar.json", capsys)
    assert not _terrain_notes(err)
    assert code != 0


def test_height_raises_a_walking_urdf_as_it_raises_go2(floor, tmp_path, capsys):
    """``--height`` is the floor of any robot that walks on terrain, not of the name go2 only."""
    urdf = write_ground_robot(tmp_path / "crawler")
    argv = ["plan", str(floor), "--start", "-0.6,0,0", "--goal", "0.6,0,0", "--time-limit", "60", "--height", "0.02"]
    code = main(argv + ["--robot", f"{urdf}:walking", "--out", str(tmp_path / "w.json")])
    err = capsys.readouterr().err
    assert code == 0, err
    code = main(argv + ["--robot", f"{urdf}", "--out", str(tmp_path / "f.json")])
    err = capsys.readouterr().err
    assert code == 2 and "--height" in err


def test_height_is_the_plane_of_every_planar_base(tmp_path):
    """``--height`` raises a planar base's floor frame: go2 and a walking URDF keep their standing
    offset on it, a planar URDF that does not walk has its base origin there."""
    from argparse import Namespace

    from splatplan.cli.plan import _robot_for
    from splatplan.robots import load_robot

    urdf = write_ground_robot(tmp_path / "crawler")

    def at(robot: str, height):
        return _robot_for(Namespace(up=None, base_pose="0.5,0,0", robot=robot, height=height, planar=False))

    assert at(f"{urdf}:planar", 0.2).base_pose[2, 3] == pytest.approx(0.2)
    walker = load_robot(f"{urdf}:walking")
    assert at(f"{urdf}:walking", 0.2).base_pose[2, 3] == pytest.approx(walker.base_pose[2, 3] + 0.2)
    assert at("go2", 0.2).base_pose[2, 3] == pytest.approx(load_robot("go2").base_pose[2, 3] + 0.2)
    assert at("go2", None).base_pose[2, 3] == pytest.approx(load_robot("go2").base_pose[2, 3])
