"""The base study's rows and report (the driving itself stubbed: the real runs take minutes)."""

from __future__ import annotations

import json

import numpy as np


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
    result = run(BaseStudyConfig.quick_config())
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
