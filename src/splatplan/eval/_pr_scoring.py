"""The scoring tasks of study E1 (:mod:`splatplan.eval.pr`) on the job engine.

:class:`PRSetup` builds the scene, the query grid, the exact labels and the evaluation set (the
same in the client and in every worker); :func:`pr_task` scores one method on every grid point
(CollisionSplatting at one n_sigma, one culled baseline with its culling check, or one fidelity
variant at one n_sigma); :func:`run_scoring` runs them all on :func:`~splatplan.eval.engine.run_tasks`.
"""

from __future__ import annotations

import functools
import hashlib
import json
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from .._resources import require_bytes
from ..errors import SplatplanError
from .._progress import progress
from ._common import DISPLAY, load_scene_with_gt
from ._pr_culling import cull_rule, culled_collision_scores, culling_check
from ._pr_config import PRConfig, variant_settings
from ..metric.config import MetricConfig  # the paper-reproduction studies run the paper's exact settings

#: bytes per grid cell across the study (centres, exact SDF, labels, every method's scores): an estimate
GRID_BYTES_PER_CELL = 128

#: sphere centres per CollisionSplatting query call
_CHUNK = 32768


def make_grid(lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[np.ndarray, dict]:
    """Cell centres of the lattice of ``spacing`` covering [lo, hi] -> ((Q, 3) float64, spec)."""
    n_float = np.maximum(1.0, np.ceil((np.asarray(hi, np.float64) - lo) / spacing - 1e-9))  # cells per axis (float: no overflow)
    require_bytes(float(np.prod(n_float)) * GRID_BYTES_PER_CELL, f"the query grid of spacing {spacing:g} ({float(np.prod(n_float)):.3g} cells)", "the resolution: a larger --spacing")
    n = n_float.astype(int)
    axes = [lo[k] + spacing * (np.arange(n[k]) + 0.5) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    spec = {"lo": lo.tolist(), "hi": (lo + spacing * n).tolist(), "spacing": spacing, "shape": n.tolist()}
    return pts, spec


def cs_query(chk: Any, pts: np.ndarray, r: float, desc: str) -> tuple[np.ndarray, np.ndarray]:
    """CollisionSplatting (min_s2, softmin), each (Q,) float64, for sphere centres ``pts`` (Q, 3)."""
    ms, sm = [], []
    for i in progress(range(0, len(pts), _CHUNK), desc=desc, unit="chunk"):
        res = chk.query(pts[i : i + _CHUNK], None, (r, r, r))
        ms.append(np.asarray(res.min_s2))
        sm.append(np.asarray(res.softmin))
    return np.concatenate(ms).astype(np.float64), np.concatenate(sm).astype(np.float64)


class PRSetup:
    """The scene, grid, labels and evaluation set of E1 (the same in the client and every worker).

    Attributes (Q_all grid points, Q of them in the evaluation set; scene units, z up):
        raw: the scene before the floater filter; splats, rep: after it and its report.
        grid (Q_all, 3), grid_spec; sdf (Q_all,) exact signed distance; label_all (Q_all,) sdf < r;
        reach (Q_all,) sdf > -r (the evaluation set); above (Q_all,) reach and z > r;
        q (Q, 3) = grid[reach]; y (Q,) labels there; near (Q,) within r/2 of the decision boundary.
    """

    def __init__(self, cfg: PRConfig) -> None:
        from ..scenes.filters import filter_floaters

        r = float(cfg.radius)
        if cfg.scene == "stonehenge":
            from ..scenes.builtin.stonehenge import build_stonehenge

            raw, geom = build_stonehenge(level=cfg.level, seed=cfg.seed, n_splats=cfg.n_splats)
            self.scene_name = f"built-in Stonehenge level {cfg.level} seed {cfg.seed}"
        else:
            raw, geom, _ = load_scene_with_gt(cfg.scene, cfg.gt, filtered=False)
            self.scene_name = str(cfg.scene)
        self.raw = raw
        self.splats, self.rep = filter_floaters(raw)  # the default rule: o < 0.1 and max std > 5x median
        lo, hi = self.splats.bounds()
        self.grid, self.grid_spec = make_grid(lo - cfg.pad * r, hi + cfg.pad * r, cfg.spacing)  # (Q_all, 3)
        self.sdf = geom.sdf(self.grid)  # (Q_all,) exact signed distance, scene units
        self.label_all = self.sdf < r
        self.reach = self.sdf > -r  # evaluation set
        self.above = self.reach & (self.grid[:, 2] > r)
        self.q = self.grid[self.reach]
        self.y = self.label_all[self.reach]
        self.near = np.abs(self.sdf[self.reach] - r) < 0.5 * r  # near the decision boundary (for the culling check)


class PRContext(PRSetup):
    """Per-worker state of E1's scoring tasks: the setup, the checkers, the torch scene tensors."""

    def __init__(self, cfg_dict: dict, device: str) -> None:
        from ..metric import CollisionChecker

        fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in cfg_dict.items()}
        cfg = PRConfig(**fields)
        super().__init__(cfg)
        self.cfg = cfg
        self.device = device
        self.checker = CollisionChecker(self.splats, n_sigma=1.0, device=device, config=MetricConfig.paper())
        self.scenes_v = {"default": self.splats, "opacity": self.raw.subset(self.raw.opacities >= cfg.eval_opacity_below)}
        self.checkers_v: dict[str, Any] = {"default": self.checker}

    def checker_v(self, kind: str):
        from ..metric import CollisionChecker

        if kind not in self.checkers_v:
            self.checkers_v[kind] = CollisionChecker(self.scenes_v[kind], n_sigma=1.0, device=self.device, config=MetricConfig.paper())
        return self.checkers_v[kind]


def make_pr_context(cfg_dict: dict, device: str) -> PRContext:
    return PRContext(cfg_dict, device)


def _baseline_task(name: str, ctx: PRContext) -> dict:
    """One culled baseline on every grid point, then its culling check (over all Gaussians)."""
    import torch

    from ..baselines import BASELINES, as_scene_tensors

    cfg, r, t0 = ctx.cfg, float(ctx.cfg.radius), time.perf_counter()
    info = BASELINES[name]
    scene_t = as_scene_tensors(ctx.splats, "cpu", torch.float32)
    full_obj = info.cls(scene_t, "cpu")
    incl, clamp, rule = cull_rule(name, full_obj, r)
    s_eval, cl_eval, n_pairs = culled_collision_scores(info.cls, scene_t, incl, clamp, ctx.q, r, cfg.tile, cfg.block, desc=DISPLAY[name])
    # deep points (sdf <= -r): far from every splat surface; same culled evaluation
    s_all = np.full(len(ctx.grid), np.nan)
    s_all[ctx.reach] = s_eval
    if (~ctx.reach).any():
        s_deep, _, _ = culled_collision_scores(info.cls, scene_t, incl, clamp, ctx.grid[~ctx.reach], r, cfg.tile, cfg.block, desc=DISPLAY[name] + " (deep)")
        s_all[~ctx.reach] = s_deep
    dt = time.perf_counter() - t0
    t1 = time.perf_counter()
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # batch-1 calls: intra-op threads only add barrier waits on a busy machine
    try:
        with torch.no_grad():
            check = culling_check(full_obj, ctx.q, s_eval, cl_eval, ctx.near, r, cfg.n_check, cfg.n_check_clamped, cfg.check_seed)
    finally:
        torch.set_num_threads(threads)
    check["seconds"] = time.perf_counter() - t1
    return {"s_all": s_all, "cl_eval": cl_eval, "n_pairs": int(n_pairs), "rule": rule, "seconds": dt, "check": check}


def pr_task(spec: dict, ctx: PRContext) -> dict:
    """One E1 scoring task (see :func:`run_scoring`): CollisionSplatting at one n_sigma, one culled
    baseline (+ its culling check) or one variant at one n_sigma. Deterministic (no RNG but the
    culling check's, seeded by ``check_seed``)."""
    r, t0 = float(ctx.cfg.radius), time.perf_counter()
    if spec["kind"] == "baseline":
        return _baseline_task(spec["name"], ctx)
    if spec["kind"] == "cs":
        chk, desc = ctx.checker.with_config(n_sigma=float(spec["n_sigma"])), "CollisionSplatting"
    else:  # "variant"
        _, kind, changes = variant_settings(spec["name"], ctx.cfg)
        chk, desc = ctx.checker_v(kind).with_config(n_sigma=float(spec["n_sigma"]), **changes), spec["name"]
    min_s2, softmin = cs_query(chk, ctx.grid, r, f"{desc} n_sigma={spec['n_sigma']:g}")
    return {"min_s2": min_s2, "softmin": softmin, "seconds": time.perf_counter() - t0}


class Scored:
    """The rows of every E1 scoring task, looked up by (kind, name, n_sigma)."""

    def __init__(self, ran, key_of: dict) -> None:
        self.ran = ran
        self.key_of = key_of
        self.engine = ran.engine

    def row(self, kind: str, name: str = "", ns: float | None = None) -> dict:
        return self.ran.rows[self.key_of[(kind, name, None if ns is None else float(ns))]]


def run_scoring(cfg: PRConfig, names: tuple[str, ...], device: str, engine, results: str | Path | None) -> Scored:
    """Every scoring task of E1 on the job engine; the baselines (the heaviest) are submitted first.

    ``results``: the JSON-lines file finished tasks stream to (a rerun with the same settings skips
    them; None = in memory only).
    """
    from .engine import Task, code_version, run_tasks

    cfg_dict = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}
    # absolute paths: a worker of an existing cluster may run in another folder
    if cfg.scene != "stonehenge":
        cfg_dict["scene"] = str(Path(cfg.scene).resolve())
    if cfg.gt is not None:
        cfg_dict["gt"] = str(Path(cfg.gt).resolve())
    src = {"config": cfg_dict, "device": device, "code": code_version()}
    sig = hashlib.sha1(json.dumps(src, sort_keys=True, default=str).encode()).hexdigest()[:8]
    specs = [("baseline", n, None) for n in names] + [("cs", "", float(ns)) for ns in cfg.n_sigmas]
    specs += [("variant", v, float(ns)) for v in cfg.variants for ns in cfg.n_sigmas]
    tasks, key_of = [], {}
    for kind, name, ns in specs:
        key = f"{sig}/{kind}" + (f"/{name}" if name else "") + ("" if ns is None else f"/ns={ns:g}")
        tasks.append(Task(key, {"kind": kind, "name": name, "n_sigma": ns}))
        key_of[(kind, name, ns)] = key
    factory = functools.partial(make_pr_context, cfg_dict, device)
    ran = run_tasks(tasks, pr_task, factory, engine, results, desc="E1 scoring")
    if ran.errors:
        k, e = next(iter(ran.errors.items()))
        where = f" (recorded in {results})" if results is not None else ""
        raise SplatplanError(f"E1: {len(ran.errors)} scoring task(s) failed{where}, e.g. {k}: {e}")
    return Scored(ran, key_of)
