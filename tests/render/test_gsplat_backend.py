"""gsplat adapter: compared with our kernels where gsplat and CUDA exist; a clean error elsewhere."""

from __future__ import annotations

import numpy as np
import pytest

import splatplan
from splatplan.errors import SplatplanError
from splatplan.render.gsplat_backend import gsplat_available

from .conftest import cameras, psnr, random_scene


@pytest.mark.skipif(gsplat_available(), reason="gsplat and CUDA present")
def test_gsplat_missing_is_a_clear_error():
    with pytest.raises(SplatplanError, match="gsplat|CUDA"):
        splatplan.render.render(random_scene(10), *cameras(8, 8), 8, 8, backend="gsplat")


@pytest.mark.skipif(not gsplat_available(), reason="needs gsplat and a CUDA device")
@pytest.mark.parametrize("sh_degree", [0, 3])
def test_gsplat_agrees_with_warp(sh_degree):
    scene = random_scene(300, sh_degree=sh_degree, disks=0.0, seed=11)
    v, k = cameras(64, 48)
    ours = splatplan.render.render(scene, v, k, 64, 48, device="cuda", background=(0.2, 0.2, 0.2))
    theirs = splatplan.render.render(scene, v, k, 64, 48, device="cuda", backend="gsplat", background=(0.2, 0.2, 0.2))
    for b in range(len(v)):
        # gsplat caps alpha at 0.999 (we: 0.99), so not bit-exact
        assert psnr(ours.rgb[b], theirs.rgb[b]) > 30.0
        assert np.abs(ours.alpha[b] - theirs.alpha[b]).mean() < 1e-2
