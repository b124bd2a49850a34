"""E5 visual reaching: the quick study's goal is hidden from the start behind the bin's front wall;
with the collision cost the arm reaches it and stays clear of the geometry, without it the arm
touches the geometry on the way (the paper's contrast); per goal and run, the study reports
whether the goal is hidden and whether the arm touched the geometry."""

from __future__ import annotations

import json

import pytest

pytestmark = pytest.mark.slow


def test_quick_reach_shows_what_the_collision_cost_does(tmp_path):
    from splatplan.eval.reach import ReachStudyConfig, report, run

    cfg = ReachStudyConfig.quick_config()
    res = run(cfg)
    report(res, tmp_path)
    data = json.loads((tmp_path / "reach.json").read_text())
    assert data["quick"] is True and data["n_goals"] == 1 and data["start_view"] == "above_bin"
    rows = {r["config"]: r for r in data["rows"]}
    with_cost = rows["with_collision"]
    # the paper's qualitative result: the goal reached with the collision cost, the arm clear of the geometry ...
    assert with_cost["successes"] == 1 and with_cost["collisions"] == 0
    assert with_cost["translation_error_m"][0] < 0.05 and with_cost["rotation_error_deg"][0] < 10.0
    assert with_cost["clearance_m"][0] > 0
    # ... and without it the arm touches the geometry on its way to the goal
    assert rows["without_collision"]["collisions"] == 1 and rows["without_collision"]["clearance_m"][0] <= 0
    (g,) = data["goals"]
    assert set(g["runs"]) == {"with_collision", "without_collision"}
    assert g["occluded"] is True and g["line_of_sight_m"] < 0  # the straight camera path runs through the wall
    assert g["runs"]["without_collision"]["touched"] and not g["runs"]["with_collision"]["touched"]
    for name, r in g["runs"].items():
        assert r["touched"] == (r["min_clearance_m"] <= 0), name
    assert rows["without_collision"]["collisions"] == sum(r["touched"] for k, r in g["runs"].items() if k == "without_collision")
    md = (tmp_path / "reach.md").read_text()
    assert "| touched |" in md and "hidden from start" in md and md.count("| goal0") == 2
