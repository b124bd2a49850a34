"""Smoke tests of the E3 / E4 studies in --quick mode (built-in Stonehenge; ~25 s together): run(config) -> result, report(result, out_dir)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.slow


def test_conservatism_quick(tmp_path):
    from splatplan.eval.conservatism import N_SIGMAS, ConservatismConfig, report, run

    out = run(ConservatismConfig.quick_config())
    assert list(tmp_path.iterdir()) == []  # run writes nothing
    assert [p.name for p in report(out, tmp_path)] == ["conservatism.json", "conservatism.md", "fig4_paths.png"]
    data = json.loads((tmp_path / "conservatism.json").read_text())
    assert [r["n_sigma"] for r in data["rows"]] == list(N_SIGMAS)
    assert set(data) == {"rows", "setup"} and data["setup"]["quick"] is True
    for r in out.rows:
        for k in ("length_rrt", "length_refined", "dmin_rrt", "dmin_refined", "smoothness_rrt", "smoothness_refined"):
            assert len(r[k]) == 2
        assert r["success_rate"] > 0
        assert r["length_refined"][0] <= r["length_rrt"][0] + 1e-9  # refinement never lengthens on average here
        assert r["clearance_refined"][0] > 0  # refined paths do not touch the true geometry
    # the study's qualitative result (paper Table II, and the full run): more conservatism, more clearance;
    # refined d_min and the true clearance grow with n_sigma (rank correlation; single rows may dip, as in the full run)
    ns = np.array([r["n_sigma"] for r in out.rows])
    for k, ratio in (("dmin_refined", 1.1), ("clearance_refined", 1.3)):
        v = np.array([r[k][0] for r in out.rows])
        rank_corr = np.corrcoef(np.argsort(np.argsort(ns)), np.argsort(np.argsort(v)))[0, 1]
        assert rank_corr > 0.6, (k, v)
        assert v[ns >= 1.5].mean() > ratio * v[ns <= 0.5].mean(), (k, v)
    assert (tmp_path / "conservatism.md").read_text().count("\n|") >= len(N_SIGMAS) + 1
    assert (tmp_path / "fig4_paths.png").stat().st_size > 10_000


def test_linearization_quick(tmp_path):
    from splatplan.eval.linearization import PLAN_LEVELS, LinearizationConfig, report, run

    out = run(LinearizationConfig.quick_config())
    assert [p.name for p in report(out, tmp_path)] == ["linearization.json", "linearization.md", "fig5_metric_along_path.png"]
    data = json.loads((tmp_path / "linearization.json").read_text())

    assert [r["level"] for r in data["rows"]] == list(PLAN_LEVELS) == [1, 2, 3]  # the paper's M1..M3
    assert all(np.isfinite(r["length"][0]) and np.isfinite(r["dmin"][0]) for r in out.rows)
    assert sorted(out.along) == list(out.setup["levels"]) and all(len(c[0]) == len(out.arc) for c in out.along.values())
    assert (tmp_path / "fig5_metric_along_path.png").stat().st_size > 10_000
    assert "M1" in (tmp_path / "linearization.md").read_text()
    # the study's qualitative result (paper Fig. 5 / Table III, and the full run): the larger and fewer
    # the splats, the more conservative the linearised metric. Along the one straight path, free for
    # the exact geometry, the conservative scaling distance drops level by level, and from M4 on the
    # same free path is called in collision (min_s2 < 1). The planner still solves every goal at
    # M1..M3 with clearance from the splats. (The full run's path lengths also grow M1 -> M3, but
    # by less than the RRT's spread over 40 goals: a 3-goal run cannot show that.)
    assert out.setup["straight_path_min_true_clearance"] > 0
    mean_s2 = [float(out.along[lv][0].mean()) for lv in sorted(out.along)]
    min_s2 = [float(out.along[lv][0].min()) for lv in sorted(out.along)]
    assert all(a > b for a, b in zip(mean_s2, mean_s2[1:])), mean_s2
    assert min_s2[0] >= min_s2[1] > min_s2[2] > 1.0 > max(min_s2[3:]), min_s2
    for r in out.rows:
        assert r["success_rate"] == 1.0 and r["dmin"][0] > 0, r
