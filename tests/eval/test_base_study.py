"""The base study: its rows and report with the driving stubbed, and the real ``--quick`` run's result."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest


def test_rows_report_each_config_with_its_meaning(tmp_path, monkeypatch):
    import splatplan.tasks.base as tb
    from splatplan.eval.base import CONFIGS, START, BaseStudyConfig, report, run
    from splatplan.tasks._common import TaskResult

    calls = []

    def fake_run_base(robot, scene, goal_xy, *, start=None, config=None, collision=True, **kw):
        calls.append((tuple(start), collision, config.memory))
        ok = collision and config.memory
        mem = {"n_sensed": 10, "n_blocked": 3, "n_queries": 40, "n_recomputes": 2, "sense_s": 0.1, "first_sense_s": 0.05, "field_s": 0.01,
               "occlusion": config.sensor_occlusion, "n_rays": 30, "n_occluded": 20, "n_opacity_queries": 90, "sight_s": 0.02} if config.memory else None  # fmt: skip
        return TaskResult(success=ok, trajectory=np.zeros((5, 3)), min_clearance_m=0.1 if collision else -0.1, final_position_error_m=0.05 if ok else 2.0,
                          time_s=1.0, steps_per_s=4.0, collision_cost=collision, clearance_source="analytic",
                          extra={"time_to_goal_s": 0.8, "n_steps": 4, "events": [], "memory": mem})  # fmt: skip

    monkeypatch.setattr(tb, "run_base", fake_run_base)
    result = run(replace(BaseStudyConfig.quick_config(), n_goals=1))  # one goal: each config run once
    assert report(result, tmp_path) == [tmp_path / "base.json", tmp_path / "base.md"]
    res = result.to_json()
    assert res["quick"] is True and res["config"]["max_steps"] == 130
    assert [r["config"] for r in res["rows"]] == list(CONFIGS) == ["with_collision", "with_collision_memory", "without_collision"]
    assert calls == [(START, True, False), (START, True, True), (START, False, False)]
    rows = {r["config"]: r for r in res["rows"]}
    assert rows["with_collision_memory"]["successes"] == 1 and rows["with_collision"]["successes"] == 0
    assert rows["without_collision"]["positive_clearance"] == 0
    assert res["memory_cost"]["sense_s"] == 0.1 and res["memory_cost"]["n_steps"] == 4
    assert res["memory_cost"]["sight_s"] == 0.02 and res["memory_cost"]["occlusion"] is True
    assert [t["memory"]["n_occluded"] for t in res["trials"] if t["memory"]] == [20]
    d = json.loads((tmp_path / "base.json").read_text())
    assert set(d["rows_meaning"]) == set(CONFIGS)
    md = (tmp_path / "base.md").read_text()
    assert all(f"| {k} |" in md and f"- `{k}`:" in md for k in CONFIGS) and "memory cost" in md and "line of sight at z = 0.30 m" in md


@pytest.fixture(scope="module")
def quick_run():
    """One real ``eval base --quick`` run (2 goals x 3 configs, about 45 s on 2 busy cores)."""
    from splatplan.eval.base import BaseStudyConfig, run

    return run(BaseStudyConfig.quick_config())


@pytest.mark.slow
def test_quick_run_memory_escapes_the_doorway_trap(quick_run, tmp_path):
    """The full run's result (benchmarks/results/base.md): with the collision cost the Go2 stays clear
    of the walls, without it drives through them; the sensed-obstacle memory reaches every goal, and
    the kitchen goal behind the too-narrow doorway in far fewer steps than plain MPPI (which stalls
    in front of it, and at best finds the way late)."""
    from splatplan.eval.base import report

    res = quick_run.to_json()
    assert res["quick"] is True
    rows = {r["config"]: r for r in res["rows"]}
    assert all(r["trials"] == 2 for r in rows.values())
    assert rows["with_collision_memory"]["successes"] == 2 and rows["with_collision_memory"]["positive_clearance"] == 2
    assert rows["with_collision"]["positive_clearance"] == 2  # the collision cost alone keeps it clear, if not always at the goal
    assert rows["without_collision"]["positive_clearance"] == 0 and rows["without_collision"]["successes"] == 0
    trials = {(t["goal"], t["config"]): t for t in res["trials"]}
    kitchen = trials[(1, "with_collision_memory")], trials[(1, "with_collision")]
    assert kitchen[0]["goal_position"][0] > 0 > kitchen[0]["goal_position"][1]  # goal 1 is in the kitchen (x > 0, y < 0), behind the narrow doorway
    assert kitchen[0]["success"] and (not kitchen[1]["success"] or kitchen[0]["n_steps"] < 0.75 * kitchen[1]["n_steps"]), kitchen
    assert res["memory_cost"]["n_steps"] > 0 and res["memory_cost"]["sense_s"] > 0
    assert [p.name for p in report(quick_run, tmp_path)] == ["base.json", "base.md"]
