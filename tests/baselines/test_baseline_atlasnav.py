"""ATLASNav against its closed form in plain numpy."""

from __future__ import annotations

import numpy as np
import torch

from splatplan.baselines.atlasnav import AtlasNav, atlasnav_score


def test_matches_numpy_closed_form(make_scene):
    sc = make_scene(300, seed=31)
    c = np.random.default_rng(32).normal(size=(77, 3)) * 0.15
    r = 0.015
    sigma = sc["scales"].mean(axis=1)
    dist = np.linalg.norm(c[:, None, :] - sc["means"][None], axis=-1)
    ref = (dist - 3 * sigma[None] - r).min(axis=1)
    np.testing.assert_allclose(atlasnav_score(sc, c, r, dtype=torch.float64), ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(atlasnav_score(sc, c, r), ref, rtol=1e-5, atol=1e-6)  # float32


def test_chunking_is_invisible(make_scene):
    sc = make_scene(100, seed=33)
    c = np.random.default_rng(34).normal(size=(50, 3)) * 0.15
    a = AtlasNav(sc, dtype=torch.float64, max_elems=3 * 100 * 4)  # 4 rows per chunk
    assert a.chunk_rows() == 4
    np.testing.assert_array_equal(a.score(c, 0.02), AtlasNav(sc, dtype=torch.float64).score(c, 0.02))
