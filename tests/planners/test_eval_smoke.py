"""Smoke tests of the E3 / E4 studies in --quick mode (built-in Stonehenge; ~25 s together)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.slow


def test_conservatism_quick(tmp_path):
    from splatplan.eval.conservatism import N_SIGMAS, run_conservatism

    out = run_conservatism(tmp_path, quick=True, seed=0)
    data = json.loads((tmp_path / "conservatism.json").read_text())
    assert [r["n_sigma"] for r in data["rows"]] == list(N_SIGMAS)
    for r in out["rows"]:
        for k in ("length_rrt", "length_refined", "dmin_rrt", "dmin_refined", "smoothness_rrt", "smoothness_refined"):
            assert len(r[k]) == 2
        assert r["success_rate"] > 0
        assert r["length_refined"][0] <= r["length_rrt"][0] + 1e-9  # refinement never lengthens on average here
        assert r["clearance_refined"][0] > 0  # refined paths do not touch the true geometry
    assert (tmp_path / "conservatism.md").read_text().count("\n|") >= len(N_SIGMAS) + 1
    assert (tmp_path / "fig4_paths.png").stat().st_size > 10_000


def test_linearization_quick(tmp_path):
    from splatplan.eval.linearization import run_linearization

    out = run_linearization(tmp_path, quick=True, seed=0)
    data = json.loads((tmp_path / "linearization.json").read_text())
    from splatplan.eval.linearization import PLAN_LEVELS

    assert [r["level"] for r in data["rows"]] == list(PLAN_LEVELS) == [1, 2, 3]  # the paper's M1..M3
    assert all(np.isfinite(r["length"][0]) and np.isfinite(r["dmin"][0]) for r in out["rows"])
    assert (tmp_path / "fig5_metric_along_path.png").stat().st_size > 10_000
    assert "M1" in (tmp_path / "linearization.md").read_text()
