"""benchmarks/encoders.py runs end to end at a tiny size (not timed here) and restores torch's thread count."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import torch


def test_encoders_benchmark_script(tmp_path, capsys):
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "encoders.py"
    spec = importlib.util.spec_from_file_location("bench_encoders", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    threads = torch.get_num_threads()
    out = tmp_path / "enc.json"
    assert mod.main(["--batch", "2", "--size", "28", "--repeats", "1", "--encoders", "thumbnail,dinov2-tiny", "--out", str(out)]) == 0
    assert torch.get_num_threads() == threads
    rows = json.loads(out.read_text())["rows"]
    assert [r["encoder"] for r in rows] == ["thumbnail16-weight-free", "dinov2-tiny-RANDOM-WEIGHTS"]
    assert all(r["images_per_s"] > 0 for r in rows)
    assert "| thumbnail16-weight-free | none (weight-free) |" in capsys.readouterr().out
    assert (tmp_path / "enc.md").exists()
