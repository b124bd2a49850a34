"""`splatplan mpc --robot go2`: the default start on the apartment and the memory flags."""

from __future__ import annotations

import json

import numpy as np

from splatplan.cli import main


def test_go2_default_start_in_apartment_is_the_study_start(tmp_path):
    from splatplan.tasks.base import START

    out = tmp_path / "run"
    rc = main(["mpc", "--robot", "go2", "--scene", "apartment", "--goal=-1.8,-0.6", "--out", str(out),
               "--base-max-steps", "2", "--base-n-samples", "8", "--base-horizon", "6", "--base-memory", "true", "--base-sensor-radius-m", "0.5"])  # fmt: skip
    assert rc in (0, 1)
    d = json.loads((out / "result.json").read_text())
    np.testing.assert_allclose(d["trajectory"][0], START)
    mem = d["extra"]["memory"]
    assert mem["sensor_radius_m"] == 0.5 and 0 < mem["n_sensed"] <= 2 * np.pi * (0.5 / 0.1) ** 2
