"""Loading memory: an INRIA ply is decoded block by block into preallocated float32 arrays, so the
peak is the output arrays plus at most one file-sized block (the issue asks for about 2x the file
plus the output; several float64 copies of the SH block used to make it 6x the file).

tracemalloc sees numpy's allocations; the timing and RSS figures for a 5M-splat file are in
``benchmarks/scene_load.py``.
"""

from __future__ import annotations

import tracemalloc

from splatplan.scenes import load_scene, save_scene
from splatplan.scenes.io_common import BLOCK_ROWS

from .scene_encoders import random_splats


def test_ply_load_peak_memory(tmp_path):
    n = 40_000
    assert n < BLOCK_ROWS  # the whole file is one block here: the worst case relative to its size
    save_scene(random_splats(n, k_sh=15, seed=0), tmp_path / "m.ply")
    file_bytes = (tmp_path / "m.ply").stat().st_size
    out_bytes = n * (3 + 4 + 3 + 1 + 3 + 45) * 4  # float32 means, quats, scales, opacities, colours, SH
    tracemalloc.start()
    try:
        s = load_scene(tmp_path / "m.ply", filter_floaters=False)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(s) == n and s.sh_rest.shape == (n, 15, 3)
    assert peak < out_bytes + 1.5 * file_bytes, (peak, out_bytes, file_bytes)
