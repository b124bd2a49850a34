"""benchmarks/robots_fk.py runs end to end at a tiny size (no timing asserted)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"


def test_robots_fk_script(tmp_path, capsys):
    sys.path.insert(0, str(BENCH))
    try:
        import robots_fk
    finally:
        sys.path.remove(str(BENCH))
    out = tmp_path / "fk.json"
    assert robots_fk.main(["--batches", "300,5000", "--repeats", "1", "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    assert {r["method"] for r in res["rows"]} == {"numpy_reference", "warp_kernel"}
    assert all(r["configs_per_s"] > 0 for r in res["rows"])
    assert "| warp_kernel | cpu | 5,000 |" in capsys.readouterr().out


def test_robots_models_script(tmp_path, capsys):
    sys.path.insert(0, str(BENCH))
    try:
        import robots_models
    finally:
        sys.path.remove(str(BENCH))
    out = tmp_path / "models.json"
    assert robots_models.main(["--models", "coarse", "--batch", "64", "--repeats", "1", "--samples", "500", "--n-splats", "3000",
                               "--mppi-steps", "1", "--mppi-splats", "20000", "--out", str(out)]) == 0  # fmt: skip
    res = json.loads(out.read_text())
    (row,) = res["rows"]
    assert row["model"] == "coarse" and row["n_ellipsoids"] == 11 and row["collides_robot_configs_per_s"] > 0
    assert row["collides_robot_configs_per_cpu_s"] > 0 and row["mpc_steps_per_s"] > 0 and row["mpc_steps_per_cpu_s"] > 0
    assert row["min_coverage_surface"] == 1.0 and row["max_reach_m"] > 0
    assert "| coarse | 11 |" in capsys.readouterr().out
