"""Throughput of the four baselines (paper Table I rows): robot poses (sphere checks) per second.

Timing protocol (per call of :func:`time_baseline`):

* the scene tensors are built once, outside the timed region (``prep_s`` reports that time);
* one untimed warm-up evaluation, then ``n_repeat`` timed evaluations; the device is synchronised
  before and after each; the rate uses the **median** time;
* batched methods (ATLASNav, SPLANNING; native batch 4096) evaluate ``batch`` centres at once
  (the first ``batch`` of ``centers``, tiled if there are fewer) -> ``checks_per_s = batch / median``;
* batch-1 methods (Splat-Nav, SAFER-Splat) evaluate one centre per call, as the originals do. A
  timed run is ``min(batch, BATCH1_SUBSET)`` such calls in a row (a small subset, default 16
  centres) and the rate is extrapolated per check: ``checks_per_s = n_subset / median``. Each call
  is independent of the others, so the extrapolation is linear.

On CUDA the peak allocated memory of the timed runs is reported (``peak_mem_gb``); on CPU it is
None (torch's CPU allocator has no counter).
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np
import torch

from ..baselines import BASELINES
from ..baselines._common import sync

#: Centres timed per run for the batch-1 baselines (rate extrapolated per check).
BATCH1_SUBSET = 16


def time_baseline(
    name: str,
    splats: Any,
    centers: np.ndarray,  # (B, 3) sphere centres, scene units
    radius: float,
    batch: int | None = None,
    device: str | torch.device = "cpu",
    n_repeat: int = 5,
    **method_kw: Any,
) -> dict:
    """Time one baseline's native score on a scene.

    Args:
        name: registry key in :data:`splatplan.baselines.BASELINES`.
        splats: the scene (Splats or mapping of arrays).
        centers: (B, 3) candidate sphere centres.
        radius: sphere radius.
        batch: centres per evaluation; None = the method's native batch. For batch-1 methods this
            is the number of one-at-a-time calls per timed run, capped at :data:`BATCH1_SUBSET`.
        device: torch device.
        n_repeat: timed runs after the warm-up.
        **method_kw: constructor keywords of the baseline class.

    Returns:
        dict with ``checks_per_s`` (from the median), ``seconds`` (each timed run),
        ``checks_per_run``, ``batch`` (centres per evaluation), ``prep_s``, ``peak_mem_gb``
        (CUDA only, else None), ``device``, ``n_splats``, ``name``.
    """
    info = BASELINES[name]
    dev = torch.device(device)
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    t0 = time.perf_counter()
    obj = info.cls(splats, dev, **method_kw)
    sync(dev)
    prep_s = time.perf_counter() - t0

    if info.native_batch == 1:
        n_calls = max(1, min(int(batch or BATCH1_SUBSET), BATCH1_SUBSET))
        sub = centers[np.arange(n_calls) % len(centers)]

        def run() -> None:
            for c in sub:
                obj.score(c[None], radius, batch=1)

        per_eval, checks = 1, n_calls
    else:
        b = int(batch or info.native_batch)
        sub = centers[np.arange(b) % len(centers)]

        def run() -> None:
            obj.score(sub, radius, batch=b)

        per_eval, checks = b, b

    run()  # warm-up
    if dev.type == "cuda":
        torch.cuda.reset_peak_memory_stats(dev)
    seconds = []
    for _ in range(max(1, int(n_repeat))):
        sync(dev)
        t = time.perf_counter()
        run()
        sync(dev)
        seconds.append(time.perf_counter() - t)
    peak = torch.cuda.max_memory_allocated(dev) / 1e9 if dev.type == "cuda" else None
    return {
        "name": name,
        "checks_per_s": checks / statistics.median(seconds),
        "seconds": seconds,
        "checks_per_run": checks,
        "batch": per_eval,
        "prep_s": prep_s,
        "peak_mem_gb": peak,
        "device": str(dev),
        "n_splats": len(obj.scene),
    }
