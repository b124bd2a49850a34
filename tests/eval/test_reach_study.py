"""E5 visual reaching: the quick study's goal is hidden from the start behind the bin's front wall;
with the collision cost the arm reaches it and stays clear of the geometry, without it the arm cuts
the wall (the paper's Table IV contrast); per goal and run, the study reports whether the goal is
hidden and whether the arm touched the geometry."""

from __future__ import annotations

import json

import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def quick_reach(tmp_path_factory):
    from splatplan.eval.reach import ReachStudyConfig, report, run

    out = tmp_path_factory.mktemp("reach")
    report(run(ReachStudyConfig.quick_config()), out)
    return json.loads((out / "reach.json").read_text()), (out / "reach.md").read_text()


def test_quick_reach_goal_is_hidden_and_the_cost_keeps_the_arm_clear(quick_reach):
    data, md = quick_reach
    assert data["quick"] is True and data["n_goals"] == 1 and data["start_view"] == "above_bin"
    rows = {r["config"]: r for r in data["rows"]}
    with_cost = rows["with_collision"]
    # with the collision cost the arm never touches the geometry
    assert with_cost["collisions"] == 0 and with_cost["clearance_m"][0] > 0
    (g,) = data["goals"]
    assert set(g["runs"]) == {"with_collision", "without_collision"}
    assert g["occluded"] is True and g["line_of_sight_m"] < 0  # the straight camera path runs through the wall
    assert not g["runs"]["with_collision"]["touched"]
    for name, r in g["runs"].items():
        assert r["touched"] == (r["min_clearance_m"] <= 0), name
    assert rows["without_collision"]["collisions"] == sum(r["touched"] for k, r in g["runs"].items() if k == "without_collision")
    assert "| touched |" in md and "hidden from start" in md and md.count("| goal0") == 2


def test_quick_reach_reaches_the_hidden_goal_only_with_the_cost_clear(quick_reach):
    data, _ = quick_reach
    rows = {r["config"]: r for r in data["rows"]}
    with_cost = rows["with_collision"]
    assert with_cost["successes"] == 1
    assert with_cost["translation_error_m"][0] < 0.05 and with_cost["rotation_error_deg"][0] < 10.0
    assert rows["without_collision"]["collisions"] == 1 and rows["without_collision"]["clearance_m"][0] <= 0
