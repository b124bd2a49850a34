"""`splatplan demo` (what `make demo` runs): pictures written, every plan found and truly collision-free.

The demo's visual-reaching part runs the E5 study's ``--quick`` settings on the study's first goal
(``quick_task_config``): that run's outcome (goal reached within 5 cm / 10 deg, clear of the
geometry) is asserted by ``tests/eval/test_reach_study.py``. Here the demo runs end to end with a
tiny controller in its place (same code path: goal sampling, renders, MPPI, figure, summary line),
so the suite does not pay for the same minute-long run twice."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from splatplan.cli import main


def _tiny_reach(monkeypatch):
    import splatplan.eval.reach as reach

    quick = reach.quick_task_config

    def tiny(cfg):
        q = quick(cfg)
        return replace(q, mppi=replace(q.mppi, n_samples=8, horizon=6, n_knots=4), plan_iters=3, image_size=16, n_views=2, n_splats=20_000)

    monkeypatch.setattr(reach, "quick_task_config", tiny)


def test_demo_writes_pictures_and_plans(tmp_path, capsys, monkeypatch):
    _tiny_reach(monkeypatch)
    assert main(["demo", "--out", str(tmp_path)]) == 0
    for name in ("collision_field.png", "plans.png", "demo_reach.png", "demo_arm.png", "demo_go2.png"):
        assert (tmp_path / name).stat().st_size > 20_000, name
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 3  # n_sigma 0, 1, 2
    clearance = np.array([float(r.split("|")[5]) for r in rows])
    assert np.all(clearance > 0)  # positive clearance to the exact geometry
    assert "visual reaching (goal0, " in out and "16x16 renders, K = 8" in out
    assert "arm (Panda, tabletop" in out and "quadruped (Go2, apartment" in out


def test_demo_reach_is_the_quick_studys_run():
    """The configuration the demo's reach runs is the one the quick study asserts on."""
    from splatplan.eval.reach import ReachStudyConfig, quick_task_config
    from splatplan.tasks.reach import ReachConfig

    assert quick_task_config(ReachConfig()) == ReachStudyConfig.quick_config().task
