"""The shared private helpers: array kinds, the progress bar, torch's thread count, Warp's cache
setting and the device default (each written once, used by every stage)."""

from __future__ import annotations

import inspect
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from splatplan._arrays import array_kind, host_array
from splatplan._progress import progress
from splatplan._warp import _cache_dir, cpu_threads, resolve_device, resolve_torch_device

REPO = Path(__file__).resolve().parents[1]


def test_array_kind_and_host_array():
    from splatplan._warp import wp as _wp

    torch = pytest.importorskip("torch")
    wp = _wp()
    a = np.arange(6, dtype=np.float32).reshape(2, 3)
    for x, kind in ((a, "numpy"), (a.tolist(), "numpy"), (torch.from_numpy(a), "torch"), (wp.array(a, dtype=wp.float32), "warp")):
        assert array_kind(x) == kind
        h = host_array(x)
        assert isinstance(h, np.ndarray)
        np.testing.assert_array_equal(h, a)


def test_progress_is_off_without_a_terminal(capsys):
    with progress(total=3, desc="x") as bar:  # pytest captures stderr: not a terminal
        bar.update(3)
        assert bar.disable
    assert list(progress(range(3))) == [0, 1, 2]


def test_cpu_threads_honours_the_environment(monkeypatch):
    monkeypatch.setenv("SPLATPLAN_CPU_THREADS", "3")
    assert cpu_threads() == 3
    monkeypatch.delenv("SPLATPLAN_CPU_THREADS")
    assert cpu_threads() >= 1


def test_set_torch_threads_restores_the_count():
    torch = pytest.importorskip("torch")
    from splatplan.eval._common import set_torch_threads

    before = torch.get_num_threads()
    want = 1 if before != 1 else 2
    with set_torch_threads(want) as n:
        assert n == want and torch.get_num_threads() == want
    assert torch.get_num_threads() == before
    with pytest.raises(RuntimeError), set_torch_threads(want):
        raise RuntimeError("boom")
    assert torch.get_num_threads() == before


def test_auto_is_the_device_everywhere():
    """"auto" resolves like the metric's Warp device for torch code too, and every public entry
    point that takes a device defaults to it."""
    torch = pytest.importorskip("torch")
    warp_dev = resolve_device("auto")
    t = resolve_torch_device("auto")
    assert t == torch.device("cpu" if warp_dev == "cpu" or not torch.cuda.is_available() else "cuda:0")
    assert resolve_torch_device(None) == t
    assert resolve_torch_device("cpu") == torch.device("cpu")

    from splatplan.baselines import BASELINES, as_scene_tensors
    from splatplan.encoders import load_encoder
    from splatplan.metric import CollisionChecker
    from splatplan.render import SplatRenderer, render
    from splatplan.robots.robot import Robot

    fns = [as_scene_tensors, load_encoder, CollisionChecker, SplatRenderer, render, Robot.fk] + [info.cls for info in BASELINES.values()]
    for fn in fns:
        assert inspect.signature(fn).parameters["device"].default == "auto", fn


def test_cache_dir_respects_the_users_choice(tmp_path):
    assert _cache_dir("/somewhere/the/user/chose", {"SPLATPLAN_WARP_CACHE": str(tmp_path)}) is None
    assert _cache_dir(None, {"SPLATPLAN_WARP_CACHE": str(tmp_path)}) == tmp_path
    assert _cache_dir(None, {"WARP_CACHE_PATH": str(tmp_path)}) is None  # Warp's own variable
    assert _cache_dir(None, {}) == REPO / "build" / "warp-cache"  # our own runs: the build tree


def test_a_kernel_cache_set_before_splatplan_stays(tmp_path):
    """A user who sets warp.config.kernel_cache_dir keeps it; Warp's banner stays off stdout."""
    code = f"""
        import warp
        warp.config.kernel_cache_dir = {str(tmp_path / "mine")!r}
        from splatplan._warp import wp
        w = wp()
        print("cache", w.config.kernel_cache_dir)
    """
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=300, cwd=REPO)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert len(lines) == 1, res.stdout  # nothing but our line: no banner
    assert lines[0].startswith("cache " + str(tmp_path / "mine")), lines


def test_lazy_thread_pool_starts_stops_and_copies_empty():
    import copy
    import pickle

    from splatplan._warp import LazyThreadPool

    p = LazyThreadPool(2, "t")
    ex = p.get()
    assert p.get() is ex and ex.submit(lambda: 3).result() == 3
    for q in (copy.copy(p), copy.deepcopy(p), pickle.loads(pickle.dumps(p))):
        assert q._pool is None and (q.threads, q.name) == (2, "t")
    p.close()
    assert p._pool is None
    assert p.get() is not ex  # a later use starts new workers
    p.close()
