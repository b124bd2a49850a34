"""Batched bidirectional RRT (RRT-Connect) on the CollisionSplatting checker.

Two trees grow, one from the start and one from the goal, and take turns. Each iteration:

1. **Extend** the active tree A towards ``batch_size`` uniform samples of the sampling box (16
   unless set: each tree grows every other iteration): the
   nearest node of A (weighted metric ``|motion_bound * dq|``, as in :mod:`.rrt`) steps at most
   ``stride`` towards each sample.
2. **Connect**: the ``connect_attempts`` new nodes closest to the other tree B are each the target
   of a *connect* from B's nearest node: a straight run towards the target (RRT-Connect's repeated
   extension). A run advances at most ``connect_strides`` strides per iteration and, while it stays
   free, goes on in the next iterations (at most ``2 * connect_attempts`` runs carried on): a run
   that hits an obstacle early wastes few checks, one in free space still reaches its target.
3. **One batched check** (``edge_stages`` collision calls, coarse to fine) covers every new edge
   of the iteration with :meth:`EdgeChecker.free_prefix`: the connect runs' free prefixes, the
   extensions' free or not (their checks stop at the first hit); at the edge resolution of the RRT (the same
   guarantee: no point of any robot ellipsoid moves more than ``edge_resolution`` between two
   consecutive checked configurations).
4. Free extensions become nodes of A. A connect run that is free up to its first colliding check
   sample adds that free part to B, one node every stride on the check-sample grid (nodes are
   always checked configurations); a run that reaches an A node whose own extension was free
   joins the trees: the path is start tree -> joint -> goal tree.

Then the path is shortcut greedily (batched edge checks, :func:`shortcut_path`): first with
doubling candidate offsets (the raw path has a vertex every stride along its connect runs, and
checking every long candidate edge from every vertex would cost more than the search), then with
every candidate on the few vertices left.

The lengths (stride, edge resolution, sampling box) are the RRT's (:meth:`RRT.settings`, derived
from the scene and the robot when unset). Nearest neighbours are exact (:class:`~.trees.Tree`): one
(N x n) distance matrix per query while a tree is small, a KD-tree over its first nodes plus that
matrix over the newest ones past :data:`~.trees.KD_MIN_NODES` nodes (the time it takes is reported
in the time split). Everything random comes from one
generator seeded by ``RRTConfig.seed``, so a run is deterministic for a seed.

Budgets: ``time_limit_s`` (and the ``deadline`` of :meth:`RRTConnect.plan`), ``max_iters`` and
``max_nodes`` are checked before each iteration (the two trees together may overshoot
``max_nodes`` by one iteration's nodes).

The result's ``info["time_split"]`` gives the seconds spent sampling (and steering), in nearest
neighbours, in collision checks, in shortcutting and the rest (setup, bookkeeping).
"""

from __future__ import annotations

import math
import time

import numpy as np
from ..errors import PlanningError
from .edges import shortcut_path
from .rrt import RRT, Search
from .rrt_types import PlanResult, path_length
from .rrt_lazy import lazy_connect_search
from .trees import Tree


class RRTConnect(RRT):
    """Batched RRT-Connect (see the module docstring); same constructor and settings as :class:`RRT`.

    Goal mode only: ``plan(start, goal)``; use :class:`RRT` to explore without a goal.
    """

    name = "rrtconnect"
    default_batch_size = 16

    def plan(self, start, goal=None, deadline: float | None = None) -> PlanResult:
        """Search a path from ``start`` to ``goal`` (configurations (D,)).

        Args:
            start, goal: (D,) configurations.
            deadline: a ``time.perf_counter()`` value the whole call (search and shortcut) stops
                by, besides ``RRTConfig.time_limit_s`` (used by :func:`~splatplan.planners.plan`
                to share one budget with the refinement).

        Raises:
            PlanningError: no goal, start or goal in collision, outside the sampling box / scene
                bounds / joint limits, or a bad box.
        """
        if goal is None:
            raise PlanningError("RRT-Connect needs a goal; use the RRT planner to explore without one")
        cfg = self.config
        s = self._setup(start, goal, deadline)
        assert s.goal is not None  # (the goal given, checked above)
        cap0 = int(min(math.inf if cfg.max_nodes is None else cfg.max_nodes, 4096))
        trees = [Tree(s.start, s.w, cap0), Tree(s.goal, s.w, cap0)]  # 0: from the start, 1: from the goal
        clock = {"sampling": 0.0, "nearest": 0.0}
        info = {"settings": s.st.as_dict(), "edge_resolution": s.st.edge_resolution, "stride": s.st.stride, "planner": self.name}
        if s.edges.edges_free(s.start[None], s.goal[None])[0]:
            return self._result(s, trees, info, clock, np.stack([s.start, s.goal]), "direct edge from start to goal is free", 0)
        if cfg.lazy:
            return self._result(s, trees, info, clock, *lazy_connect_search(self, s, trees, info, clock))
        it = 0
        runs: list[tuple[int, int, int, int]] = []  # connect runs still free, carried to the next iteration
        while (message := s.stop(cfg, it, trees[0].n + trees[1].n, info)) is None:
            a_id = it % 2
            it += 1
            base, near, new = self._extend(s, trees[a_id], clock)  # 1. extend A towards uniform samples
            todo, c_from, c_to, frac = self._connect_runs(s, trees, a_id, new, runs, clock)  # 2. connect B towards them
            # 3. one collision call for every edge of the iteration: the connect runs' free prefixes,
            # the extensions only free or not
            m = len(new)
            exact = np.arange(m + len(c_from)) >= m
            k, n = s.edges.free_prefix(np.concatenate([base, c_from]), np.concatenate([new, c_to]), exact=exact)
            t0 = time.perf_counter()
            # 4. grow A by the free extensions, B by the free part of each connect run; join the trees
            ext_free = k[:m] == n[:m]  # (M,)
            new_ids = np.full(m, -1, dtype=np.int64)
            if ext_free.any():
                new_ids[ext_free] = trees[a_id].add(new[ext_free], near[ext_free])
            raw = _joined(trees, todo, new_ids, k[m:], n[m:], frac)
            if raw is None:
                runs = self._grow_runs(s, trees, todo, new_ids, k[m:], n[m:], frac, c_from, c_to)
            clock["sampling"] += time.perf_counter() - t0
            if raw is not None:
                return self._result(s, trees, info, clock, raw, f"trees joined after {it} iterations", it)
        return self._result(s, trees, info, clock, None, f"no path found {message}", it)

    def _extend(self, s: Search, ta: Tree, clock: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steer from A's nearest nodes at most ``stride`` towards ``batch_size`` uniform samples:
        (base (M, D), their node ids (M,), new configurations (M, D))."""
        t1 = time.perf_counter()
        samples = s.sample(self.batch_size)  # (N, D)
        sz = samples * s.w
        t2 = time.perf_counter()
        near = ta.nearest(sz)  # (N,)
        t3 = time.perf_counter()
        base = ta.nodes[near]
        dist = np.linalg.norm(sz - ta.zs[near], axis=1)  # (N,) metric distance
        ok = dist > 1e-12
        base, near, dist, samples = base[ok], near[ok], dist[ok], samples[ok]
        step = np.minimum(dist, s.st.stride) / np.maximum(dist, 1e-300)
        new = base + (samples - base) * step[:, None]  # (M, D) steer: at most `stride` towards the sample
        new[:, s.frozen] = s.st.box_lo[s.frozen]
        clock["sampling"] += (t2 - t1) + (time.perf_counter() - t3)
        clock["nearest"] += t3 - t2
        return base, near, new

    def _connect_runs(self, s: Search, trees: list[Tree], a_id: int, new: np.ndarray, runs: list, clock: dict):
        """The connect runs of an iteration: from B's nearest nodes towards the ``connect_attempts``
        new nodes closest to B, plus the runs carried on. Returns (todo, c_from (C, D), c_to (C, D),
        frac (C,)): a run is (tree it grows, its front node, tree of the target, target node id or
        -1 - index into ``new``), tried now up to ``c_to``, the share ``frac`` of the way."""
        tb, w, d = trees[1 - a_id], s.w, s.start.size
        m = len(new)
        t4 = time.perf_counter()
        near_b = tb.nearest(new * w) if m else np.zeros(0, dtype=np.int64)  # (M,)
        t5 = time.perf_counter()
        d_b = np.linalg.norm(new * w - tb.zs[near_b], axis=1)  # (M,)
        pick = np.argsort(d_b, kind="stable")[: min(int(self.config.connect_attempts), m)]  # (C,) indices into new
        todo = [(1 - a_id, int(near_b[j]), a_id, -1 - int(j)) for j in pick] + runs
        c_from = np.array([trees[f].nodes[i] for f, i, _, _ in todo]).reshape(-1, d)  # (C, D)
        c_tgt = np.array([new[-1 - t] if t < 0 else trees[g].nodes[t] for _, _, g, t in todo]).reshape(-1, d)
        c_len = np.linalg.norm((c_tgt - c_from) * w, axis=1)  # (C,)
        strides = self.config.connect_strides
        conn_len = math.inf if strides is None else float(strides) * s.st.stride
        frac = np.minimum(1.0, conn_len / np.maximum(c_len, 1e-300))  # (C,) share of the run tried now
        clock["nearest"] += t5 - t4
        clock["sampling"] += time.perf_counter() - t5
        return todo, c_from, c_from + (c_tgt - c_from) * frac[:, None], frac

    def _grow_runs(self, s: Search, trees: list[Tree], todo: list, new_ids: np.ndarray, kc, nc, frac, c_from, c_to) -> list:
        """Add the free part of each connect run to its tree, one node every stride on the
        check-sample grid (nodes are always checked configurations) and the last free sample;
        returns the runs free so far that go on in the next iteration."""
        runs: list[tuple[int, int, int, int]] = []
        for c, (f, i_from, g, tgt) in enumerate(todo):
            if kc[c] == 0:
                continue
            seg = float(np.linalg.norm((c_to[c] - c_from[c]) * s.w))
            every = max(1, int(s.st.stride * nc[c] / max(seg, 1e-300)))
            ii = np.arange(every, kc[c] + 1, every)
            if ii.size == 0 or ii[-1] != kc[c]:
                ii = np.append(ii, kc[c])
            pts = c_from[c] + (ii / nc[c])[:, None] * (c_to[c] - c_from[c])  # (K, D)
            tree = trees[f]
            ids = tree.add(pts, np.concatenate([[i_from], np.arange(tree.n, tree.n + len(ii) - 1)]))
            if tgt < 0:
                tgt = int(new_ids[-1 - tgt])
            if kc[c] == nc[c] and frac[c] < 1.0 and tgt >= 0 and len(runs) < 2 * int(self.config.connect_attempts):
                runs.append((f, int(ids[-1]), g, tgt))  # free so far: the run goes on next iteration
        return runs

    def _result(self, s: Search, trees: list[Tree], info: dict, clock: dict, path: np.ndarray | None, message: str, it: int) -> PlanResult:
        """The result (both trees, start tree first), the path shortcut when found, the time split."""
        ta, tb = trees
        d, w, edges, cfg = s.start.size, s.w, s.edges, self.config
        nodes = np.concatenate([ta.nodes[: ta.n], tb.nodes[: tb.n]])
        parents = np.concatenate([ta.parents[: ta.n], np.where(tb.parents[: tb.n] >= 0, tb.parents[: tb.n] + ta.n, -1)])
        res = PlanResult(
            success=path is not None, path=np.zeros((0, d)) if path is None else path,
            length=math.inf if path is None else path_length(path, w), time_s=0.0, n_nodes=ta.n + tb.n, n_iters=it,
            tree_nodes=nodes, tree_parents=parents, message=message, path_rrt=None if path is None else path.copy(),
            info={**info, "tree_sizes": [ta.n, tb.n]},
        )  # fmt: skip
        t_short = time.perf_counter()
        c_search, q_before = edges.time_s, edges.n_queries
        if path is not None and cfg.shortcut and len(res.path) > 2:
            dl = None if math.isinf(s.end) else s.end
            if (info.get("lazy") or {}).get("shortcut") != "doubling":  # (the lazy search's path is shortcut so already)
                res.path = shortcut_path(edges, res.path, deadline=dl, candidates="doubling", screen=cfg.shortcut_screen)
            if len(res.path) > 3:  # (with 3 vertices the one candidate edge was just checked)
                res.path = shortcut_path(edges, res.path, deadline=dl, screen=cfg.shortcut_screen)  # every candidate on the few vertices left
            res.length = path_length(res.path, w)
        t_now = time.perf_counter()
        res.time_s = t_now - s.t0
        split = {"sampling": clock["sampling"], "nearest": clock["nearest"], "collision": c_search + clock.get("collision_nodes", 0.0), "shortcut": t_now - t_short}
        split["other"] = max(0.0, res.time_s - sum(split.values()))
        res.info.update(time_split=split, n_queries=edges.n_queries - s.q0, n_queries_shortcut=edges.n_queries - q_before, n_configs=edges.n_configs - s.c0)
        return res


def _joined(trees: list[Tree], todo: list, new_ids: np.ndarray, kc: np.ndarray, nc: np.ndarray, frac: np.ndarray) -> np.ndarray | None:
    """The raw path (P, D) start -> goal when a connect run reached its target node whole and free
    (the target of a run towards a new node exists if that node's extension was free), else None."""
    for c, (f, i_from, g, tgt) in enumerate(todo):
        if tgt < 0:
            tgt = int(new_ids[-1 - tgt])
        if tgt >= 0 and kc[c] == nc[c] and frac[c] >= 1.0:
            ps, pg = trees[f].trace(i_from), trees[g].trace(tgt)  # root of f -> joint, root of g -> joint
            return np.vstack([ps, pg[::-1]]) if f == 0 else np.vstack([pg, ps[::-1]])
    return None
