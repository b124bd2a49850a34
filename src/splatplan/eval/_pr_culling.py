"""Exact spatial culling of E1's baselines (:mod:`splatplan.eval.pr`, "Exact spatial culling").

Per baseline: an inclusion radius R_i per Gaussian and a clamp (:func:`cull_rule`); every tile of
nearby queries is scored against the Gaussians that can matter to it
(:func:`culled_collision_scores`); :func:`culling_check` re-scores a random sample over all
Gaussians and reports the largest deviation.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ..errors import SplatplanError
from .._progress import progress
from .._warp import cpu_threads


def cull_rule(name: str, obj: Any, r: float) -> tuple[np.ndarray, float | None, str]:
    """(per-Gaussian inclusion radius R_i (N,), clamp in collision-score units or None, text).

    See the module docstring for the derivation of each rule.
    """
    if name == "splatnav":
        s = obj.lam.max(dim=-1).values.sqrt().double().numpy()  # level-scaled largest std
        return 2.1 * (r + s), -4.0, "clamp max_t K >= 4; keep |c-mu| < 2.1 (r + s_max)"
    if name == "safersplat":
        s = obj.semi_axes.max(dim=-1).values.double().numpy()
        return 2.05 * r + s, -3.0 * r * r, "clamp h >= 3 r^2 (d >= 2r); keep |c-mu| < 2.05 r + s_max"
    if name == "atlasnav":
        return 2.01 * r + obj.ball.double().numpy(), -r, "clamp score >= r; keep |c-mu| < 2.01 r + 3 sigma"
    if name == "splanning":
        return (obj.cull.double().numpy() + r) * (1 + 1e-4) + 1e-6, None, "no clamp; keep |c-mu| <= 6 s_max + r (native cull)"
    raise SplatplanError(f"no culling rule for baseline {name!r}")


def _box_dist(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Euclidean distance (P,) from points (P, 3) to the axis-aligned box [lo, hi] (0 inside)."""
    d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return np.sqrt(np.einsum("ij,ij->i", d, d))


def _subset(scene_t: Any, idx: np.ndarray) -> Any:
    """SceneTensors restricted to Gaussians ``idx``."""
    import torch

    from ..baselines import SceneTensors

    t = torch.as_tensor(idx, dtype=torch.long)
    return SceneTensors(scene_t.means[t], scene_t.rotations[t], scene_t.scales[t], scene_t.opacities[t])


def culled_collision_scores(
    cls: type,
    scene_t: Any,  # SceneTensors of the full scene
    incl_radius: np.ndarray,  # (N,) Gaussian i can matter for centre c only if |c - mu_i| < R_i
    clamp: float | None,  # collision-score floor (None: no clamp)
    queries: np.ndarray,  # (Q, 3) sphere centres, scene units
    radius: float,
    tile: float,
    block: float,
    desc: str = "",
) -> tuple[np.ndarray, np.ndarray, int]:
    """A baseline's collision score on many queries, each tile against its nearby Gaussians only.

    Returns:
        (scores (Q,) float64, clamped (Q,) bool, number of (query, Gaussian) pairs evaluated).
        Queries with no candidate get ``clamp`` (or the method's score against an empty
        neighbourhood, 0, when ``clamp`` is None: SPLANNING's p with I = 0).
    """
    import torch

    means = scene_t.means.double().numpy()  # (N, 3)
    q = np.asarray(queries, dtype=np.float64)
    floor = 0.0 if clamp is None else clamp
    out = np.full(len(q), floor)
    clamped = np.ones(len(q), bool) if clamp is not None else np.zeros(len(q), bool)
    origin = q.min(0)
    tkey = np.floor((q - origin) / tile).astype(np.int64)  # (Q, 3) tile index
    per_block = max(1, int(min(round(block / tile), 2**40)))  # a block larger than the domain is one block (no int64 overflow)
    bkey = tkey // per_block
    order = np.lexsort((tkey[:, 2], tkey[:, 1], tkey[:, 0], bkey[:, 2], bkey[:, 1], bkey[:, 0]))
    tk, bk = tkey[order], bkey[order]
    t_start = np.r_[0, np.nonzero(np.any(tk[1:] != tk[:-1], axis=1))[0] + 1, len(q)]
    b_start = np.r_[0, np.nonzero(np.any(bk[1:] != bk[:-1], axis=1))[0] + 1, len(q)]
    def tiles():  # yields (query ids, Gaussian ids) per tile with candidates
        ti = 0
        for b0, b1 in zip(b_start[:-1], b_start[1:]):
            bq = q[order[b0:b1]]
            cand = np.nonzero(_box_dist(means, bq.min(0), bq.max(0)) < incl_radius)[0]  # block candidates
            while ti < len(t_start) - 1 and t_start[ti] < b1:
                qi = order[t_start[ti] : t_start[ti + 1]]
                ti += 1
                if len(cand) == 0:
                    yield qi, None
                    continue
                tq = q[qi]
                keep = cand[_box_dist(means[cand], tq.min(0), tq.max(0)) < incl_radius[cand]]
                yield qi, (keep if len(keep) else None)

    def evaluate(task):
        qi, keep = task
        if keep is None:
            return qi, None, 0
        obj = cls(_subset(scene_t, keep), "cpu")
        s = np.asarray(obj.collision_score(q[qi], radius, batch=len(qi)), dtype=np.float64)
        return qi, s, len(qi) * len(keep)

    n_pairs = 0
    bar = progress(total=len(t_start) - 1, desc=desc, unit="tile")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # one tile per core: the tiles are too small for intra-op threads
    try:
        with ThreadPoolExecutor(max_workers=cpu_threads()) as pool:
            for qi, s, n in pool.map(evaluate, tiles()):
                bar.update(1)
                if s is None:
                    continue
                n_pairs += n
                if clamp is None:
                    out[qi] = s
                else:
                    out[qi] = np.maximum(s, clamp)
                    clamped[qi] = s <= clamp
    finally:
        torch.set_num_threads(threads)
    bar.close()
    return out, clamped, n_pairs


def culling_check(
    full_obj: Any,  # the baseline over all Gaussians
    queries: np.ndarray,  # (Q, 3) sphere centres
    scores: np.ndarray,  # (Q,) culled scores
    clamped: np.ndarray,  # (Q,) bool, tied at the clamp
    near: np.ndarray,  # (Q,) bool, near the decision boundary
    radius: float,
    n_check: int,
    n_check_clamped: int,
    seed: int,
) -> dict[str, Any]:
    """Re-score ``n_check`` random unclamped queries near the boundary and ``n_check_clamped``
    clamped ones over all Gaussians; report the largest deviation from the culled run."""
    rng = np.random.default_rng(seed)
    pick_near = np.nonzero(near & ~clamped)[0]
    pick_cl = np.nonzero(clamped)[0]
    a = rng.choice(pick_near, min(n_check, len(pick_near)), replace=False) if len(pick_near) else np.zeros(0, int)
    b = rng.choice(pick_cl, min(n_check_clamped, len(pick_cl)), replace=False) if len(pick_cl) else np.zeros(0, int)
    idx = np.r_[a, b].astype(int)
    if len(idx) == 0:
        return {"n": 0}
    full = np.concatenate([np.asarray(full_obj.collision_score(queries[i : i + 1], radius, batch=1), np.float64) for i in idx])
    dev_exact = np.abs(full[: len(a)] - scores[a])
    rel = dev_exact / np.maximum(np.abs(full[: len(a)]), 1e-30)
    viol = full[len(a) :] - scores[b]  # clamped: the full score must be <= the clamp (<= 0 here)
    return {
        "n": int(len(idx)),
        "n_clamped": int(len(b)),
        "max_abs_dev": float(dev_exact.max()) if len(a) else 0.0,
        "max_rel_dev": float(rel.max()) if len(a) else 0.0,
        "max_clamp_violation": float(max(0.0, viol.max())) if len(b) else 0.0,
    }

