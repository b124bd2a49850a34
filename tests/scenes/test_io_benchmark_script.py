"""benchmarks/scene_load.py runs end to end at a tiny size (timings are not checked here; the
recorded figures live in benchmarks/results/scene_load.json)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"


def test_scene_load_script(tmp_path, capsys, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    import scene_load

    out = tmp_path / "scene_load.json"
    assert scene_load.main(["--n", "3000", "--sh-degree", "1", "--tasks", "load_raw", "--tmp", str(tmp_path), "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    assert [r["task"] for r in res["rows"]] == ["load_scene(filter_floaters=False)"]
    assert all(r["peak_rss_bytes"] > 0 and r["time_s"] > 0 for r in res["rows"])
    assert (tmp_path / "scene_load.md").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith("splatplan_scene_load_")] == []  # temp ply deleted
    assert "| load_scene(filter_floaters=False) | inria ply |" in capsys.readouterr().out
    sys.modules.pop("scene_load", None)
