"""`splatplan mpc` bad input: one-line errors, exit code 2, nothing run."""

from __future__ import annotations

import pytest

from splatplan.cli import main


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--robot", "panda", "--goal-pose", "2.5,0,0.2,0,1,0,0"], "unreachable goal pose"),
        (["--robot", "panda", "--goal-pose", "0.5,0,0.2,0,0,0,0"], "quaternion"),
        (["--robot", "panda", "--goal-pose", "0.5,0,0.2"], "expected 7"),
        (["--robot", "panda"], "needs --goal-pose"),
        (["--robot", "go2"], "needs --goal"),
        (["--robot", "go2", "--goal", "nan,1"], "finite"),
        (["--robot", "go2", "--goal", "40,1"], "outside the scene"),
        (["--robot", "go2", "--goal", "1,1", "--scene", "no_such_file.ply"], "neither a built-in scene"),
    ],
)
def test_bad_input(argv, message, tmp_path, capsys):
    assert main(["mpc", *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_no_collision_is_said_everywhere(tmp_path, capsys):
    import json

    out = tmp_path / "run"
    rc = main(["mpc", "--robot", "go2", "--goal=-1.8,-0.6", "--start=-2.3,-0.6,0", "--no-collision", "--out", str(out),
               "--base-max-steps", "3", "--base-mppi-n-samples", "8", "--base-mppi-horizon", "6"])  # fmt: skip
    assert rc in (0, 1)
    printed = capsys.readouterr().out
    assert "--no-collision" in printed and printed.count("collision cost OFF") == 2
    d = json.loads((out / "result.json").read_text())
    assert d["collision_cost"] is False and "--no-collision" in d["note"]
    assert set(d) >= {"success", "trajectory", "min_clearance_m", "final_position_error_m", "time_s", "steps_per_s"}
    assert (out / "motion.png").stat().st_size > 1000


def test_scene_file_without_ground_truth_uses_the_metric(tmp_path, capsys):
    import json

    from splatplan.scenes.builtin import write_builtin

    ply, gt = write_builtin("apartment", tmp_path / "apt.ply")
    gt.unlink()
    out = tmp_path / "run"
    rc = main(["mpc", "--robot", "go2", "--scene", str(ply), "--goal=-1.8,-0.6", "--start=-2.3,-0.6,0", "--out", str(out),
               "--base-max-steps", "3", "--base-mppi-n-samples", "8", "--base-mppi-horizon", "6"])  # fmt: skip
    assert rc in (0, 1)
    d = json.loads((out / "result.json").read_text())
    assert d["clearance_source"] == "metric" and "metric" in d["clearance_note"] and "(metric)" in capsys.readouterr().out
