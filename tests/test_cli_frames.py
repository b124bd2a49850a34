"""One frame vocabulary in the CLI: --base-pose, leading minus signs, NaN flags, the removed plan --up."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main
from splatplan.cli._common import parse_base_pose, robot_at
from splatplan.errors import SplatplanError

BANANA = Path(__file__).resolve().parent / "data" / "equinor_banana_splat.ply"


def test_parse_base_pose():
    p = parse_base_pose("-0.5,1,2")
    np.testing.assert_allclose(p[:3, 3], [-0.5, 1, 2])
    np.testing.assert_allclose(p[:3, :3], np.eye(3))
    p = parse_base_pose("0,0,0,0,0,0,2")  # 180 deg about z, normalised
    np.testing.assert_allclose(p[:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    for bad, needle in (("0,0,0,0,0,0,0", "zero"), ("nan,0,0", "finite"), ("1,2", "3 numbers"), ("a,b,c", "numbers")):
        with pytest.raises(SplatplanError, match=needle):
            parse_base_pose(bad)


def test_robot_at_moves_the_base():
    pose = parse_base_pose("0.5,-0.2,0.7")
    panda = robot_at("panda", pose)
    home = robot_at("panda", None)
    c1, _, _ = panda.ellipsoids(panda.q_default[None])
    c0, _, _ = home.ellipsoids(home.q_default[None])
    np.testing.assert_allclose(c1 - c0, np.broadcast_to([0.5, -0.2, 0.7], c0.shape), atol=1e-9)
    go2 = robot_at("go2", parse_base_pose("0,0,0.1"))
    np.testing.assert_allclose(go2.base_pose[2, 3], robot_at("go2", None).base_pose[2, 3] + 0.1)


def test_cli_base_pose_and_bad_flags(tmp_path, capsys):
    np.save(tmp_path / "q.npy", np.zeros((2, 3)))
    ok = ["check", str(BANANA), "--robot", "go2", "--configs", str(tmp_path / "q.npy"), "--base-pose", "-0.1,0,-0.2,1,0,0,0"]
    assert main(ok) == 0
    capsys.readouterr()
    cases = [
        (["check", str(BANANA), "--robot", "go2", "--configs", str(tmp_path / "q.npy"), "--base-pose", "0,0,0,0,0,0,0"], "quaternion"),
        (["check", str(BANANA), "--robot", "go2", "--configs", str(tmp_path / "q.npy"), "--n-sigma", "nan"], "n_sigma"),
        (["plan", str(BANANA), "--robot", "go2", "--start", "0,0,0", "--goal", "0.1,0,0", "--out", str(tmp_path / "p.json"), "--up", "-y"], "scene align"),
        (["plan", str(BANANA), "--robot", "go2", "--start", "0,0,0", "--goal", "0.1,0,0", "--out", str(tmp_path / "p.json"), "--height", "nan"], "--height"),
        (["render", str(BANANA), "--eye", "-0.6,0.1,nan", "--look-at", "0,0,0", "--out", str(tmp_path / "r.png")], "--eye"),
    ]
    for argv, needle in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("splatplan: error:") and needle in err and err.count("\n") == 1, (argv, err)


def test_leading_minus_is_a_value(tmp_path):
    out = tmp_path / "v.png"
    assert main(["render", str(BANANA), "--eye", "-0.6,0.3,0.2", "--look-at", "0.1,0.05,-0.1", "--width", "32", "--height", "24", "--out", str(out), "--device", "cpu"]) == 0
    assert out.is_file()


def test_plan_panda_goal_pose_by_ik(tmp_path, capsys):
    import json

    from splatplan.robots import load_robot

    out = tmp_path / "p.json"
    argv = ["plan", str(BANANA), "--robot", "panda", "--base-pose", "1.5,1.5,0", "--start", ",".join(map(str, load_robot("panda").q_default)),
            "--goal-pose", "2.0,1.7,0.3,0,1,0,0", "--time-limit", "5", "--out", str(out), "--device", "cpu"]  # fmt: skip
    assert main(argv) == 0, capsys.readouterr().err
    assert "IK goal configuration" in capsys.readouterr().err
    q = np.asarray(json.loads(out.read_text())["path"])[-1]
    robot = robot_at("panda", parse_base_pose("1.5,1.5,0"))
    t = robot.link_poses(q)[list(robot.link_names).index("panda_hand_tcp")]
    np.testing.assert_allclose(t[:3, 3], [2.0, 1.7, 0.3], atol=0.01)
    bad = ["plan", str(BANANA), "--robot", "panda", "--start", "0,0,0,-1,0,1,0", "--goal-pose", "9,9,9,1,0,0,0", "--out", str(out)]
    assert main(bad) == 2 and "unreachable" in capsys.readouterr().err
