"""E2 throughput: the quick study's schema, the memory probe, bad input."""

from __future__ import annotations

import json
import os
from dataclasses import replace

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.eval._harness import proc_status_mb, reset_peak_rss, timed_runs
from splatplan.eval.throughput import ThroughputConfig, ThroughputResult, markdown, report, run

EXPECTED_ROWS = {("splatnav", 1), ("safersplat", 1), ("atlasnav", 4096), ("splanning", 4096), ("collisionsplatting", 4096), ("collisionsplatting", 32768)}


@pytest.fixture(scope="module")
def quick_tp(tmp_path_factory):
    out = tmp_path_factory.mktemp("tp")
    res = run(ThroughputConfig.quick_config())
    assert [p.name for p in report(res, out)] == ["throughput.json", "throughput.md"]
    return out, res


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
    assert markdown(ThroughputResult(**data)) == md  # the table is a function of the JSON alone


def test_quick_throughput_keeps_the_full_runs_result(quick_tp):
    """The quick study's qualitative result is the full run's (paper Table I): batched
    CollisionSplatting checks several times faster than every baseline (paper CPU: 5.7x the
    fastest; ours in the full run: two orders of magnitude)."""
    _, res = quick_tp
    rate = {(r["method"], r["batch"]): r["checks_per_s"] for r in res.to_json()["rows"]}
    ours = rate[("collisionsplatting", 4096)]
    fastest = max(v for (m, _), v in rate.items() if m != "collisionsplatting")
    assert ours > 5.0 * fastest, rate
    assert rate[("collisionsplatting", 32768)] > 5.0 * fastest, rate


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="needs Linux /proc")
def test_memory_probe_sees_an_allocation():
    import mmap

    assert reset_peak_rss()
    rss0 = proc_status_mb("VmRSS")
    # 64 MiB of fresh anonymous pages, every page touched: an np.ones of that size can come from
    # heap pages an earlier test freed but glibc kept resident, and then the RSS does not rise
    buf = mmap.mmap(-1, 64 * 2**20)
    np.frombuffer(buf, dtype=np.uint8)[:: mmap.PAGESIZE] = 1
    assert proc_status_mb("VmHWM") - rss0 > 60
    buf.close()


def test_timed_runs_counts_wall_and_cpu_time():
    calls = []
    wall, cpu = timed_runs(lambda: calls.append(sum(range(20000))), 3, sync=lambda: calls.append("sync"))
    assert len(wall) == len(cpu) == 3 and all(w > 0 and c >= 0 for w, c in zip(wall, cpu))
    assert calls[1::2] == ["sync"] * 3  # the device is synchronised after every call, inside the timing


def test_bad_device_and_rows():
    with pytest.raises(SplatplanError, match="device"):
        run(replace(ThroughputConfig.quick_config(), device="tpu"))
    with pytest.raises(SplatplanError, match="unknown throughput row"):
        run(replace(ThroughputConfig.quick_config(), rows=(("nomethod", 4),)))
