"""Search trees: the nearest-neighbour answer (KD-tree past KD_MIN_NODES nodes, brute force over the
nodes added since, removed nodes skipped) is the brute-force one, as the tree grows and loses subtrees."""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

from splatplan.planners import trees as T


def _brute(tree: T.Tree, z: np.ndarray) -> np.ndarray:
    d = cdist(z, tree.zs[: tree.n], "sqeuclidean")
    d[:, ~tree.valid[: tree.n]] = np.inf
    return np.argmin(d, axis=1)


def test_nearest_is_the_brute_force_answer_while_growing_and_pruning(monkeypatch):
    monkeypatch.setattr(T, "KD_MIN_NODES", 64)  # (small trees: the KD path runs early)
    rng = np.random.default_rng(0)
    d = 7
    w = rng.uniform(0.5, 2.0, d)
    tree = T.Tree(rng.normal(size=d), w, cap=16)
    used_kd = False
    for step in range(60):
        k = int(rng.integers(1, 40))
        parents = rng.integers(0, tree.n, k)
        tree.add(rng.normal(size=(k, d)), parents)
        if step % 7 == 3:  # remove a few subtrees (never the root)
            tree.invalidate(rng.integers(1, tree.n, 2))
        z = rng.normal(size=(33, d)) * w
        got = tree.nearest(z)
        np.testing.assert_array_equal(got, _brute(tree, z))
        assert tree.valid[got].all()
        used_kd |= tree._kd is not None
    assert used_kd and tree.n > 500
