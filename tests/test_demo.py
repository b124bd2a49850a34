"""`splatplan demo` (what `make demo` runs): pictures written, every plan found and truly collision-free."""

from __future__ import annotations

import numpy as np

from splatplan.cli import main


def test_demo_writes_pictures_and_plans(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "collision_field.png").stat().st_size > 20_000
    assert (tmp_path / "plans.png").stat().st_size > 20_000
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 3  # n_sigma 0, 1, 2
    clearance = np.array([float(r.split("|")[5]) for r in rows])
    assert np.all(clearance > 0)  # positive clearance to the exact geometry
