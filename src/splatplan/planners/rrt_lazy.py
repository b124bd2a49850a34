"""The lazy search of RRT-Connect (``RRTConfig.lazy``): nodes checked during the search, edges only
when they could finish a path.

Most of an eager search's collision checks go to edges that never end up on the path: every
extension edge is checked at the edge resolution the moment it is grown (an arm edge of one stride
is 10-30 configurations). The lazy search (Bohlin and Kavraki's lazy evaluation, applied to
RRT-Connect) checks those edges only when they could finish a path:

1. **Extend** the active tree A towards ``batch_size`` uniform samples, as the eager search does;
   only the new configurations are checked (one configuration each).
2. **Connect**: for the ``connect_attempts`` new nodes closest to the other tree B, a straight run
   from B's nearest node to the new node, with a node every stride; only those nodes are checked.
   A run's free nodes join B (up to its first colliding node); a run whose every node is free,
   ending on a free new node, makes a *candidate path* start tree -> joint -> goal tree.
3. Steps 1 and 2 share **one batched check** per iteration.
4. **Validation**: the candidate paths' unchecked edges are checked at the edge resolution
   (:meth:`~.rrt.EdgeChecker.edges_free`, one batched call, each edge stopping at its first hit).
   Checked edges are remembered; an edge that collides removes its child node and the child's
   whole subtree from its tree (:meth:`~.trees.Tree.invalidate`). The first candidate whose edges
   are all free is the path.

**The guarantee is the eager search's**: every edge of the returned path was checked at the edge
resolution (no point of any robot ellipsoid moves more than ``edge_resolution`` between two
consecutive checked configurations), the vertices are checked configurations. Only which path is
found, and how many configurations it takes, differ.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .rrt import _Search
from .trees import Tree


def lazy_connect_search(planner, s: _Search, trees: list[Tree], info: dict, clock: dict) -> tuple[np.ndarray | None, str, int]:
    """Run the lazy search (module docstring) on ``trees`` (0: rooted at the start, 1: at the goal).

    Args:
        planner: the :class:`~.rrt_connect.RRTConnect` (its config and its extension step).
        s: the search's set-up.
        info: gets ``lazy`` statistics (candidate validations, edges checked and removed).
        clock: seconds by phase; gets ``collision_nodes`` (the node checks).

    Returns:
        (raw path (P, D) start -> goal or None, message, iterations).
    """
    cfg = planner.config
    w, stride = s.w, float(s.st.stride)
    stats = {"validations": 0, "edges_checked": 0, "edges_rejected": 0, "nodes_removed": 0}
    info["lazy"] = stats
    clock.setdefault("collision_nodes", 0.0)
    it = 0
    while (message := s.stop(cfg, it, trees[0].n + trees[1].n, info)) is None:
        a_id = it % 2
        it += 1
        ta, tb = trees[a_id], trees[1 - a_id]
        _, near, new = planner._extend(s, ta, clock)  # 1. new configurations (M, D) from A's nodes `near`
        m = len(new)
        if m == 0:
            continue
        t0 = time.perf_counter()
        zb = new * w
        near_b = tb.nearest(zb)  # (M,)
        t1 = time.perf_counter()
        d_b = np.linalg.norm(zb - tb.zs[near_b], axis=1)  # (M,)
        pick = np.argsort(d_b, kind="stable")[: min(int(cfg.connect_attempts), m)]  # (C,) indices into new
        runs = []  # 2. per connect run: its inner nodes (K, D), every stride from B's node towards new[j]
        for j in pick:
            k = max(1, int(math.ceil(d_b[j] / stride)))
            f = np.arange(1, k)[:, None] / k  # (K - 1, 1): the end node is new[j] itself
            src = tb.nodes[near_b[j]]
            runs.append(src + f * (new[j] - src))
        clock["nearest"] += t1 - t0
        clock["sampling"] += time.perf_counter() - t1
        t2 = time.perf_counter()
        hit = s.edges.configs_collide(np.concatenate([new, *runs]))  # 3. one check: (M + sum K,)
        clock["collision_nodes"] += time.perf_counter() - t2
        t3 = time.perf_counter()
        ext_free = ~hit[:m]
        new_ids = np.full(m, -1, dtype=np.int64)
        if ext_free.any():
            new_ids[ext_free] = ta.add(new[ext_free], near[ext_free], verified=False)
        candidates = []  # (node of B, node of A) at the same configuration
        off = m
        for j, pts in zip(pick, runs):
            h = hit[off : off + len(pts)]
            off += len(pts)
            n_free = len(pts) if not h.any() else int(np.argmax(h))
            whole = n_free == len(pts) and bool(ext_free[j])
            chain = np.vstack([pts[:n_free], new[j : j + 1]]) if whole else pts[:n_free]
            if len(chain):
                ids = tb.add(chain, np.concatenate([[near_b[j]], np.arange(tb.n, tb.n + len(chain) - 1)]), verified=False)
                if whole:
                    candidates.append((int(ids[-1]), int(new_ids[j])))
        clock["sampling"] += time.perf_counter() - t3
        if candidates:
            path = _validate(s, trees, a_id, candidates, stats)  # 4.
            if path is not None:
                return path, f"trees joined after {it} iterations ({stats['validations']} candidate path(s) checked)", it
    return None, f"no path found {message}", it


def _validate(s: _Search, trees: list[Tree], a_id: int, candidates: list[tuple[int, int]], stats: dict) -> np.ndarray | None:
    """Check the unchecked edges of the candidate paths (one batched call); remove the subtrees of
    the colliding ones; the first candidate left whole, as a path (P, D) start -> goal, or None."""
    stats["validations"] += 1
    tb_id = 1 - a_id
    per_cand, todo = [], {}
    for ib, ia in candidates:
        ids = {a_id: trees[a_id].trace_ids(ia), tb_id: trees[tb_id].trace_ids(ib)}
        per_cand.append(ids)
        for t, chain in ids.items():
            for i in chain[1:].tolist():
                if not trees[t].verified[i]:
                    todo[(t, i)] = None
    keys = list(todo)
    if keys:
        a = np.array([trees[t].nodes[trees[t].parents[i]] for t, i in keys])  # (K, D) parents
        b = np.array([trees[t].nodes[i] for t, i in keys])  # (K, D) children
        free = s.edges.edges_free(a, b)
        stats["edges_checked"] += len(keys)
        for t in (0, 1):
            sel = np.array([k[0] == t for k in keys])
            ids = np.array([k[1] for k in keys], dtype=np.int64)
            trees[t].verified[ids[sel & free]] = True
            bad = ids[sel & ~free]
            if bad.size:
                stats["edges_rejected"] += int(bad.size)
                stats["nodes_removed"] += trees[t].invalidate(bad)
    for ids in per_cand:
        if all(bool(trees[t].valid[chain].all()) for t, chain in ids.items()):
            fa, fb = trees[a_id].nodes[ids[a_id]], trees[tb_id].nodes[ids[tb_id]]  # root of A -> joint, root of B -> joint
            return np.vstack([fa, fb[::-1][1:]]) if a_id == 0 else np.vstack([fb, fa[::-1][1:]])
    return None
