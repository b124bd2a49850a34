"""_warp.launch_split: every thread index is launched exactly once, with its chunk's offset."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from splatplan._warp import launch_split
from splatplan._warp import wp as _wp

wp = _wp()


@wp.kernel
def _count_kernel(scale: int, offset: int, hits: wp.array(dtype=wp.int32)):
    i = wp.tid() + offset
    wp.atomic_add(hits, i, scale)


@pytest.mark.parametrize("dim", [0, 1, 255, 256, 1000, 4097])
@pytest.mark.parametrize("workers", [1, 3])
def test_every_index_once(dim, workers):
    hits = wp.zeros(max(dim, 1), dtype=wp.int32, device="cpu")
    with ThreadPoolExecutor(max_workers=workers) as pool:
        launch_split(_count_kernel, dim, [2, 0, hits], "cpu", pool, offset_at=1, min_split=256, min_step=100, chunks_per_thread=4)
    h = hits.numpy()[:dim]
    np.testing.assert_array_equal(h, np.full(dim, 2))


def test_no_pool_is_one_launch():
    hits = wp.zeros(500, dtype=wp.int32, device="cpu")
    launch_split(_count_kernel, 500, [1, 77, hits], "cpu", None, offset_at=1)  # the offset input is reset to 0
    np.testing.assert_array_equal(hits.numpy(), np.ones(500))
