"""The arm study's real ``--quick`` run asserts the full run's result (benchmarks/results/arm.md)."""

from __future__ import annotations

import json

import pytest


@pytest.fixture(scope="module")
def quick_run():
    """One ``eval arm --quick`` run (2 targets x with / without the collision cost, about 40 s on 2 busy cores)."""
    from splatplan.eval.arm import ArmStudyConfig, run

    return run(ArmStudyConfig.quick_config())


@pytest.mark.slow
def test_quick_run_lifts_over_the_wall(quick_run, tmp_path):
    """With the collision cost the Panda reaches every target behind the wall and stays clear of the
    boxes; without it the direct motion cuts through the wall (negative clearance) on every target."""
    from splatplan.eval.arm import report

    d = quick_run.to_json()
    assert d["quick"] is True and d["throughput"] is None
    rows = {r["config"]: r for r in d["rows"]}
    w, wo = rows["with_collision"], rows["without_collision"]
    assert w["trials"] == wo["trials"] == 2
    assert w["successes"] == 2 and w["positive_clearance"] == 2 and w["min_clearance_m"][0] > 0
    assert wo["positive_clearance"] == 0 and wo["successes"] == 0 and wo["min_clearance_m"][0] < 0
    for t in d["trials"]:
        if t["config"] == "with_collision":
            assert t["final_error_m"] < 0.02 and t["min_clearance_m"] > 0, t
    assert [p.name for p in report(quick_run, tmp_path)] == ["arm.json", "arm.md"]
    assert json.loads((tmp_path / "arm.json").read_text())["rows"][0]["config"] == "with_collision"
