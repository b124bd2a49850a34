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
4. **Validation by shortcut**: a candidate path is checked while it is shortcut (the doubling
   candidates of :func:`~.rrt.shortcut_path`, screened, then checked whole farthest first): from
   each kept vertex the farthest free candidate edge is taken, and only where no candidate is free
   is the path's own next edge checked. Tree edges that a shortcut jumps over are never checked.
   A tree edge that collides removes its child node and the child's whole subtree from its tree
   (:meth:`~.trees.Tree.invalidate`) and the search goes on; checked tree edges are remembered.
   The first candidate that passes is the path (already shortcut once; the planner's final
   shortcut pass tries every candidate on the few vertices left). With ``RRTConfig.shortcut``
   off, a candidate's unchecked edges are checked as they are (one batched call).

**The guarantee is the eager search's**: every edge of the returned path was checked at the edge
resolution (no point of any robot ellipsoid moves more than ``edge_resolution`` between two
consecutive checked configurations), the vertices are checked configurations. Only which path is
found, and how many configurations it takes, differ.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .edges import first_free
from .rrt import Search
from .trees import Tree


def lazy_connect_search(planner, s: Search, trees: list[Tree], info: dict, clock: dict) -> tuple[np.ndarray | None, str, int]:
    """Run the lazy search (module docstring) on ``trees`` (0: rooted at the start, 1: at the goal).

    Args:
        planner: the :class:`~.rrt_connect.RRTConnect` (its config and its extension step).
        s: the search's set-up.
        info: gets ``lazy`` statistics (candidate paths checked, tree edges rejected, nodes removed,
            configurations checked at the nodes and in the validations).
        clock: seconds by phase; gets ``collision_nodes`` (the node checks).

    Returns:
        (raw path (P, D) start -> goal or None, message, iterations).
    """
    cfg = planner.config
    w, stride = s.w, float(s.st.stride)
    stats: dict[str, Any] = {"validations": 0, "edges_rejected": 0, "nodes_removed": 0, "configs_nodes": 0, "configs_validation": 0,
             "shortcut": "doubling" if cfg.shortcut else None}  # fmt: skip
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
        c0 = s.edges.n_configs
        hit = s.edges.configs_collide(np.concatenate([new, *runs]))  # 3. one check: (M + sum K,)
        stats["configs_nodes"] += s.edges.n_configs - c0
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
            c0 = s.edges.n_configs
            path = _validate(s, trees, a_id, candidates, stats, cfg.shortcut_screen, bool(cfg.shortcut))  # 4.
            stats["configs_validation"] += s.edges.n_configs - c0
            if path is not None:
                return path, f"trees joined after {it} iterations ({stats['validations']} candidate path(s) checked)", it
    return None, f"no path found {message}", it


def _candidate(trees: list[Tree], a_id: int, ib: int, ia: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """A candidate path start -> goal through the joint (node ``ia`` of A and ``ib`` of B hold the
    same configuration): its vertices (P, D) and, per edge k (vertex k -> k + 1), the tree edge it
    is (tree, child node id)."""
    f, ids_f, g, ids_g = (a_id, trees[a_id].trace_ids(ia), 1 - a_id, trees[1 - a_id].trace_ids(ib))
    if a_id == 1:  # the start tree is B
        f, ids_f, g, ids_g = g, ids_g, f, ids_f
    path = np.vstack([trees[f].nodes[ids_f], trees[g].nodes[ids_g[::-1][1:]]])
    owners = [(f, int(i)) for i in ids_f[1:]] + [(g, int(i)) for i in ids_g[::-1][:-1]]
    return path, owners


def _shortcut_check(s: Search, trees: list[Tree], path: np.ndarray, owners: list[tuple[int, int]], screen: int | None) -> tuple[np.ndarray | None, tuple[int, int] | None]:
    """Shortcut a candidate path while checking it (VALIDATION BY SHORTCUT, module docstring).

    From each kept vertex, the doubling candidates of :func:`~.rrt.shortcut_path` (screened, then
    checked whole farthest first); where none is free, the path's own next edge is checked (unless
    already checked). Returns (the shortcut path, every edge checked, None) or (None, the tree edge
    (tree, child node id) that collides)."""
    edges = s.edges
    p = path
    out = [0]
    i = 0
    while i < len(p) - 1:
        off = 1 + 2 ** np.arange(int(math.log2(max(1, len(p) - 1 - i))) + 1)  # 2, 3, 5, 9, ...
        cand = np.unique(np.append(i + off[i + off < len(p) - 1], len(p) - 1))
        cand = cand[cand >= i + 2][::-1]  # farthest first
        j = i + 1
        if cand.size:
            j = first_free(edges, p, i, cand, int(screen or 0)) or j
        if j == i + 1:
            t, node = owners[i]
            if not trees[t].verified[node]:
                if not edges.edges_free(p[i : i + 1], p[i + 1 : i + 2])[0]:
                    return None, (t, node)
                trees[t].verified[node] = True
        out.append(j)
        i = j
    return p[out], None


def _validate(s: Search, trees: list[Tree], a_id: int, candidates: list[tuple[int, int]], stats: dict, screen: int | None, shortcut: bool) -> np.ndarray | None:
    """Check the candidate paths one by one, by shortcutting them (:func:`_shortcut_check`) or, with
    ``shortcut`` off, edge by edge as they are; a colliding tree edge removes its child's subtree.
    The first candidate that passes (shortcut or not), or None."""
    for ib, ia in candidates:
        if not (trees[1 - a_id].valid[ib] and trees[a_id].valid[ia]):
            continue  # (a subtree removed by an earlier candidate of this iteration)
        stats["validations"] += 1
        path, owners = _candidate(trees, a_id, ib, ia)
        if not all(trees[t].valid[i] for t, i in owners):
            continue
        if shortcut:
            # a cheap first look: every screen-th sample of the unchecked tree edges (a hit there is a
            # hit of the edge's own check: the edge collides)
            todo = [k for k, (t, i) in enumerate(owners) if not trees[t].verified[i]]
            ok = s.edges.screen(path[todo], path[[k + 1 for k in todo]], int(screen or 64)) if todo else np.ones(0, dtype=bool)
            bad_edges = [owners[k] for k, f in zip(todo, ok.tolist()) if not f]
            if bad_edges:
                for t, i in bad_edges:
                    stats["edges_rejected"] += 1
                    stats["nodes_removed"] += trees[t].invalidate(np.array([i]))
                continue
            short, bad = _shortcut_check(s, trees, path, owners, screen)
            if short is not None:
                return short
            assert bad is not None  # (no path: the edge that collides)
            bad_edges = [bad]
        else:  # the path as it is: every unchecked edge in one call
            todo = [k for k, (t, i) in enumerate(owners) if not trees[t].verified[i]]
            free = s.edges.edges_free(path[todo], path[[k + 1 for k in todo]]) if todo else np.ones(0, dtype=bool)
            for k, f in zip(todo, free.tolist()):
                if f:
                    trees[owners[k][0]].verified[owners[k][1]] = True
            bad_edges = [owners[k] for k, f in zip(todo, free.tolist()) if not f]
            if not bad_edges:
                return path
        for t, i in bad_edges:
            stats["edges_rejected"] += 1
            stats["nodes_removed"] += trees[t].invalidate(np.array([i]))
    return None
