"""Search trees of the sampling planners: node configurations in flat numpy arrays, grown in place.

A :class:`Tree` holds (cap, D) configurations, their images in the planner's weighted metric (for
nearest-neighbour search) and parent indices. Nodes are appended after their parents, so a parent's
index is always smaller than its child's. Nearest neighbours are exact: brute force while the tree is
small; past :data:`KD_MIN_NODES` nodes a KD-tree over the first nodes (rebuilt as the tree grows by a
quarter) plus brute force over the nodes added since, with a brute-force answer for any query whose
KD-tree answer was removed. For lazy searches a node also carries whether the edge from
its parent has been checked (``verified``) and whether it is still part of the tree (``valid``):
:meth:`Tree.invalidate` removes nodes with their whole subtrees, which then never come back from
:meth:`Tree.nearest`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

#: metric coordinate given to removed nodes: never the nearest (its square stays finite in float64)
_FAR = 1e150
#: trees up to this many nodes answer nearest-neighbour queries by brute force only (one distance
#: matrix beats building a KD-tree there)
KD_MIN_NODES = 2048
#: a KD-tree over the first nodes is rebuilt once the nodes added since exceed this share of it
KD_REBUILD_SHARE = 0.25


def sq_dists(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, D), (M, D) -> (N, M) squared Euclidean distances (scipy's ``cdist``, imported on first use: a
    program that only builds the command line does not load scipy.spatial)."""
    from scipy.spatial.distance import cdist

    return cdist(a, b, "sqeuclidean")


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
        self._kd: cKDTree | None = None  # over zs[:_kd_n] as they were when built (removed nodes included)
        self._kd_n = 0

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
        if self.n < KD_MIN_NODES:
            return np.argmin(sq_dists(z, self.zs[: self.n]), axis=1)
        if self._kd is None or self.n - self._kd_n > KD_REBUILD_SHARE * self._kd_n:
            self._kd_n = self.n
            from scipy.spatial import cKDTree

            self._kd = cKDTree(self.zs[: self.n].copy())
        d_kd, i_kd = self._kd.query(z, k=1)  # (N,), (N,): among the first _kd_n nodes as built
        i_kd = np.asarray(i_kd, dtype=np.int64)
        d2 = np.asarray(d_kd, dtype=np.float64) ** 2
        out = i_kd.copy()
        if self.n > self._kd_n:  # the nodes added since the build, by brute force
            tail = sq_dists(z, self.zs[self._kd_n : self.n])  # (N, n - kd_n)
            j = np.argmin(tail, axis=1)
            t2 = tail[np.arange(len(z)), j]
            closer = t2 < d2
            out[closer] = self._kd_n + j[closer]
        gone = ~self.valid[i_kd] & (out == i_kd)  # the KD-tree's answer was removed since: exact by brute force
        if gone.any():
            out[gone] = np.argmin(sq_dists(z[gone], self.zs[: self.n]), axis=1)
        return out

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
