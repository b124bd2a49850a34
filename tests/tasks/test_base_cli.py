"""`splatplan mpc --robot go2`: the default start on the apartment and the memory flags."""

from __future__ import annotations

import json

import numpy as np

from splatplan.cli import main


def test_go2_default_start_in_apartment_is_the_study_start(tmp_path):
    from splatplan.tasks.base import START

    out = tmp_path / "run"
    rc = main(["mpc", "--robot", "go2", "--scene", "apartment", "--goal=-1.8,-0.6", "--out", str(out),
               "--base-max-steps", "2", "--base-mppi-n-samples", "8", "--base-mppi-horizon", "6", "--base-memory", "true", "--base-sensor-radius-m", "0.5"])  # fmt: skip
    assert rc in (0, 1)
    d = json.loads((out / "result.json").read_text())
    np.testing.assert_allclose(d["trajectory"][0], START)
    mem = d["extra"]["memory"]
    assert mem["sensor_radius_m"] == 0.5 and 0 < mem["n_sensed"] <= 2 * np.pi * (0.5 / 0.1) ** 2


def test_bad_memory_flags_exit_2_with_one_line(tmp_path, capsys):
    """Impossible memory settings are named on one stderr line, exit 2, and no result is written."""
    for flag, value in (("--base-memory-cell-m", "0"), ("--base-sensor-radius-m", "-1"), ("--base-sensor-height-m", "nan"), ("--base-memory-yaws", "0")):
        out = tmp_path / flag.strip("-")
        rc = main(["mpc", "--robot", "go2", "--scene", "apartment", "--goal=1.1,1.8", "--out", str(out), "--base-memory", "true", flag, value])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2, (flag, err)
        assert len(err) == 1 and flag in err[0] and "Traceback" not in err[0], (flag, err)  # names the flag (declared range, issue #21)
        assert not out.exists(), (flag, "a rejected run leaves no output folder")


def test_a_rejected_run_keeps_an_existing_folder_and_its_files(tmp_path, capsys):
    """Only folders the command made, and only when empty, are removed on failure."""
    out = tmp_path / "kept"
    out.mkdir()
    (out / "mine.txt").write_text("x")
    nested = tmp_path / "a" / "b" / "c"
    for target in (out, nested):
        rc = main(["mpc", "--robot", "go2", "--scene", "apartment", "--goal=1.1,1.8", "--out", str(target), "--base-memory", "true", "--base-memory-yaws", "0"])
        assert rc == 2
    capsys.readouterr()
    assert (out / "mine.txt").read_text() == "x"
    assert not (tmp_path / "a").exists()
