"""E2 throughput: the quick study's schema, the memory probe, bad input."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.eval.throughput import proc_status_mb, reset_peak_rss, run_throughput

EXPECTED_ROWS = {("splatnav", 1), ("safersplat", 1), ("atlasnav", 4096), ("splanning", 4096), ("collisionsplatting", 4096), ("collisionsplatting", 32768)}


@pytest.fixture(scope="module")
def quick_tp(tmp_path_factory):
    out = tmp_path_factory.mktemp("tp")
    return out, run_throughput(out, quick=True)


def test_quick_throughput_outputs(quick_tp):
    out, _ = quick_tp
    data = json.loads((out / "throughput.json").read_text())
    assert data["device"] == "cpu"
    assert {(r["method"], r["batch"]) for r in data["rows"]} == EXPECTED_ROWS
    for r in data["rows"]:
        assert "error" not in r, r
        assert isinstance(r["method"], str) and isinstance(r["batch"], int)
        assert isinstance(r["checks_per_s"], float) and r["checks_per_s"] > 0
        assert isinstance(r["peak_mem_mb"], float) and np.isfinite(r["peak_mem_mb"]) and r["peak_mem_mb"] >= 0
    md = (out / "throughput.md").read_text()
    assert "| method | batch |" in md and "13,653.3" in md and "Splat-Nav" in md
    assert data["quick"] is True


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="needs Linux /proc")
def test_memory_probe_sees_an_allocation():
    assert reset_peak_rss()
    rss0 = proc_status_mb("VmRSS")
    a = np.ones(64 * 2**20 // 8)  # 64 MiB, touched
    assert proc_status_mb("VmHWM") - rss0 > 60
    del a


def test_bad_device(tmp_path):
    with pytest.raises(SplatplanError):
        run_throughput(tmp_path, quick=True, device="tpu")
