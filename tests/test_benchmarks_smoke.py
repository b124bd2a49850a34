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


def test_gpu_rates_script_on_cpu(tmp_path, capsys):
    """benchmarks/gpu_rates.py (made for a lent GPU) runs on CPU too: Panda rows with the per-cost
    split, the query-alone and lanes timings, the tuning rows and one tiny reach row."""
    import gpu_rates

    out = tmp_path / "g.json"
    argv = ["--device", "cpu", "--quick", "--samples", "8", "--lanes-sweep", "1,2", "--tune-factors", "0.25", "--tune-lanes", "1", "--tune-group-links", "0,1",
            "--reach-size", "16", "--reach-horizon", "6", "--reach-plan-iters", "2", "--reach-encoders", "thumbnail", "--out", str(out)]  # fmt: skip
    assert gpu_rates.main(argv) == 0
    res = json.loads(out.read_text())
    (p,) = res["panda"]
    assert p["K"] == 8 and p["steps_per_s"] > 0 and "_final_x" not in p
    assert set(p["cost_s_per_step"]) == {"CollisionCost", "GoalPoseCost", "ControlEffortCost", "JointLimitCost"}
    assert {"numpy_q", "device_q_workspace", "lanes_1", "lanes_2"} <= set(p["query_only_s"]) and p["query_only_s"]["lanes_default"] == 1
    assert len(res["tune"]) == 2 and all(t["seconds"] > 0 for t in res["tune"]) and {t["group_links"] for t in res["tune"]} == {False, True}
    (r,) = res["reach"]
    assert r["image_size"] == 16 and r["mpc_steps"] == 6 and r["mpc_steps_per_s"] > 0
    assert "| Panda MPPI" in capsys.readouterr().out and out.with_suffix(".md").exists()


def test_reach_goal_filters_script(tmp_path, capsys):
    """benchmarks/reach_goal_filters.py: per model, the candidates left after each filter in turn
    never grow, and the behind-wall ones are a part of them."""
    import reach_goal_filters

    out = tmp_path / "f.json"
    assert reach_goal_filters.main(["--models", "tight,coarse", "--n-candidates", "64", "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    assert set(res["models"]) == {"tight", "coarse"} and res["models"]["tight"]["n_ellipsoids"] > res["models"]["coarse"]["n_ellipsoids"]
    for m in res["models"].values():
        steps = m["after"]
        assert [s["filter"] for s in steps] == ["move", "turn", "clearance", "metric", "self_collision", "view"]
        alls, behind = [s["all"] for s in steps], [s["behind_wall"] for s in steps]
        assert alls == sorted(alls, reverse=True) and behind == sorted(behind, reverse=True) and m["behind_wall"] >= behind[0]
        assert all(b <= a for a, b in zip(alls, behind)) and alls[0] <= 64
    assert "| camera in `BEHIND_WALL` |" in capsys.readouterr().out and out.with_suffix(".md").exists()
