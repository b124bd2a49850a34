"""Search trees of the sampling planners: node configurations in flat numpy arrays, grown in place.

A :class:`Tree` holds (cap, D) configurations, their images in the planner's weighted metric (for
nearest-neighbour search) and parent indices. Nodes are appended after their parents, so a parent's
index is always smaller than its child's. For lazy searches a node also carries whether the edge from
its parent has been checked (``verified``) and whether it is still part of the tree (``valid``):
:meth:`Tree.invalidate` removes nodes with their whole subtrees, which then never come back from
:meth:`Tree.nearest`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

#: metric coordinate given to removed nodes: never the nearest (its square stays finite in float64)
_FAR = 1e150


class Tree:
    """One tree: (cap, D) node configurations, their metric images and parents, grown in place.

    Args:
        root: (D,) the root configuration (its edge counts as verified).
        w: (D,) configuration -> metric multipliers.
        cap: initial capacity (doubled when full).
    """

    def __init__(self, root: np.ndarray, w: np.ndarray, cap: int) -> None:
        d = root.size
        self.w = w
        self.nodes = np.empty((cap, d))  # (cap, D) configurations
        self.zs = np.empty((cap, d))  # (cap, D) the same in the weighted metric (_FAR when removed)
        self.parents = np.full(cap, -1, dtype=np.int64)  # (cap,)
        self.verified = np.zeros(cap, dtype=bool)  # (cap,) the edge parent -> node was checked
        self.valid = np.ones(cap, dtype=bool)  # (cap,) still in the tree
        self.nodes[0], self.zs[0], self.verified[0] = root, root * w, True
        self.n = 1

    def add(self, q: np.ndarray, parents: np.ndarray, verified: bool = True) -> np.ndarray:
        """Append nodes (K, D) with parents (K,) (earlier nodes, or earlier rows of this call);
        returns their ids (K,)."""
        k = len(q)
        if self.n + k > len(self.nodes):
            cap = max(2 * len(self.nodes), self.n + k)
            for name, fill in (("nodes", 0.0), ("zs", 0.0), ("parents", -1), ("verified", False), ("valid", True)):
                a = getattr(self, name)
                b = np.full((cap,) + a.shape[1:], fill, dtype=a.dtype)
                b[: self.n] = a[: self.n]
                setattr(self, name, b)
        ids = np.arange(self.n, self.n + k)
        self.nodes[ids], self.zs[ids], self.parents[ids] = q, q * self.w, parents
        self.verified[ids], self.valid[ids] = verified, True
        self.n += k
        return ids

    def nearest(self, z: np.ndarray) -> np.ndarray:
        """(N, D) metric points -> (N,) index of the nearest node still in the tree."""
        return np.argmin(cdist(z, self.zs[: self.n], "sqeuclidean"), axis=1)

    def trace(self, i: int) -> np.ndarray:
        """(P, D) configurations from the root to node i."""
        return self.nodes[self.trace_ids(i)].copy()

    def trace_ids(self, i: int) -> np.ndarray:
        """(P,) node ids from the root to node i."""
        idx = []
        while i >= 0:
            idx.append(i)
            i = int(self.parents[i])
        return np.asarray(idx[::-1], dtype=np.int64)

    def invalidate(self, ids: np.ndarray) -> int:
        """Remove nodes ``ids`` (never the root) and every descendant; returns how many nodes left
        the tree. Parents precede children, so one pass in id order reaches every descendant."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        ids = ids[ids > 0]
        if ids.size == 0:
            return 0
        before = int(self.valid[: self.n].sum())
        self.valid[ids] = False
        lo = int(ids.min())
        par = self.parents[lo : self.n]
        for i, p in zip(range(lo, self.n), par.tolist()):  # parents precede children
            if p >= 0 and not self.valid[p]:
                self.valid[i] = False
        gone = ~self.valid[: self.n]
        self.zs[: self.n][gone] = _FAR
        return before - int(self.valid[: self.n].sum())
