"""The benchmark scripts run end to end at tiny sizes (they are not timed here; timings live in
benchmarks/results and the README)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(BENCH))


def test_metric_throughput_script(tmp_path, capsys):
    import metric_throughput

    out = tmp_path / "m.json"
    assert metric_throughput.main(["--batches", "512", "--repeats", "1", "--out", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert {r["method"] for r in rows} == {"collisionsplatting", "collisionsplatting_collision_only"}
    assert all(r["checks_per_s"] > 0 for r in rows)
    assert "| collisionsplatting | 512 |" in capsys.readouterr().out


def test_planners_script(tmp_path):
    import planners

    out = tmp_path / "p.json"
    assert planners.main(["--goals", "2", "--quick", "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["rrt"]["success_rate"] == 1.0
    assert res["rrt"]["paths_with_colliding_splats"] == 0
    assert res["mppi"]["steps_in_collision"] == 0
    assert (tmp_path / "planners.md").exists()
