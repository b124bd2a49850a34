"""The render benchmark script runs end to end at a tiny size (no timing asserted)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

BENCH = Path(__file__).parents[2] / "benchmarks" / "render.py"


def test_render_benchmark_smoke(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("bench_render", BENCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = tmp_path / "r.json"
    ex = tmp_path / "ex.png"
    assert mod.main(["--n-splats", "3000", "--batch", "3", "--sizes", "16,40", "--repeats", "1", "--out", str(out), "--example", str(ex)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert [r["size"] for r in rows] == [16, 40] and all(r["images_per_s"] > 0 for r in rows)
    assert ex.stat().st_size > 0
    assert "| warp | 16x16 |" in capsys.readouterr().out
