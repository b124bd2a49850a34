"""Study E6's real ``--quick`` run asserts the full run's result (benchmarks/results/navigate.md)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def quick_run():
    """One ``eval navigate --quick`` run (5 targets, about 40 s on 2 busy cores)."""
    from splatplan.eval.navigate import NavigateStudyConfig, run

    return run(NavigateStudyConfig.quick_config())


@pytest.mark.slow
def test_quick_run_retrieves_and_reaches_the_targets(quick_run, tmp_path):
    """The image of a held-out pose retrieves a tree node near it for most targets (full run: 9 of
    10 within 0.5 m), the Go2 reaches every retrieved node, and no executed path touches the scene."""
    from splatplan.eval.navigate import RETRIEVAL_RADIUS_M, report

    d = quick_run.data
    assert d["quick"] is True and len(d["trials"]) == 5
    errs = sorted(t["retrieval_error_m"] for t in d["trials"])
    assert d["retrieval_rate"] >= 0.6 and errs[2] < RETRIEVAL_RADIUS_M / 2, errs  # most retrieved, the median well within the radius
    assert all(t["reached"] for t in d["trials"])
    assert d["all_paths_collision_free"] and all(t["min_clearance_m"] > 0 for t in d["trials"])
    assert d["success_rate"] >= 0.6
    names = [p.name for p in report(quick_run, tmp_path)]
    assert names[:3] == ["navigate.json", "navigate.md", "navigate_tree.png"] and len(names) == 3 + 5
