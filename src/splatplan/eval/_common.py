"""Shared helpers of the studies (E1 precision-recall and E2 throughput first of all).

Units and frames: normalised scene units of the built-in Stonehenge (z up, ground top at z = 0,
x, y in [-0.5, 0.5]); robot = a sphere of radius :data:`ROBOT_RADIUS` (scene units).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ..scenes.filters import FilterReport, filter_floaters
from ..scenes.splats import Splats

#: The paper's robot: a sphere of this radius (scene units).
ROBOT_RADIUS = 0.015

#: Display names, in the order rows are printed.
DISPLAY = {
    "splatnav": "Splat-Nav",
    "safersplat": "SAFER-Splat",
    "atlasnav": "ATLASNav",
    "splanning": "SPLANNING",
    "collisionsplatting": "CollisionSplatting",
}


def n_cores() -> int:
    """CPU cores this process may run on (affinity mask), >= 1; ``SPLATPLAN_CPU_THREADS`` when set
    (a local job-engine worker gets cores / N, so N workers share the cores, not N x all of them)."""
    env = os.environ.get("SPLATPLAN_CPU_THREADS")
    if env:
        return max(1, int(env))
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def set_torch_threads() -> int:
    """Let torch use every core (the baselines are torch code). Returns the thread count."""
    import torch

    n = n_cores()
    torch.set_num_threads(n)
    return n


def load_stonehenge_filtered(level: int = 1, seed: int = 0, n_splats: int | None = None):
    """The built-in Stonehenge with floaters filtered (as the paper does).

    Returns:
        (splats, analytic_scene, filter_report).
    """
    from ..scenes.stonehenge import build_stonehenge

    splats, scene = build_stonehenge(level=level, seed=seed, n_splats=n_splats)
    splats, rep = filter_floaters(splats)
    return splats, scene, rep


def load_scene_with_gt(path: str | Path, gt: str | Path | None, filtered: bool = True) -> tuple[Splats, object, FilterReport | None]:
    """A splat file and its analytic ground truth (``.gt.json`` written by ``splatplan scene``).

    Args:
        path: the splat file.
        gt: its ground truth.
        filtered: drop floaters with the default rule (the report is None when False).

    Raises:
        SplatplanError: no ``gt`` given or a file is missing.
    """
    from ..scenes.load import load_scene
    from ..scenes.primitives import AnalyticScene

    if gt is None:
        raise SplatplanError(
            f"scene {str(path)!r} needs its ground truth for precision-recall: pass --gt PATH.gt.json "
            "(written beside the .ply by 'splatplan scene stonehenge --out PATH.ply'), or use --scene stonehenge"
        )
    gt_path = Path(gt)
    if not gt_path.is_file():
        raise SplatplanError(f"ground-truth file {str(gt_path)!r} not found")
    if not Path(path).is_file():
        raise SplatplanError(f"scene file {str(path)!r} not found")
    splats = load_scene(path, filter_floaters=False)
    rep = None
    if filtered:
        splats, rep = filter_floaters(splats)
    return splats, AnalyticScene.load(gt_path), rep


def mean_std(values, finite_only: bool = False) -> list[float]:
    """[mean, std] of ``values`` (only their finite ones with ``finite_only``); [nan, nan] when there are none."""
    v = np.asarray([x for x in values if not finite_only or np.isfinite(x)], dtype=np.float64)
    return [float(v.mean()), float(v.std())] if v.size else [float("nan"), float("nan")]


def config_rows(trials: list[dict], fields: tuple[str, ...], extra=None, configs: tuple[str, ...] = ("with_collision", "without_collision")) -> list[dict]:
    """Summary rows of a study, one per name in ``configs`` (trials carry it as ``"config"``): [mean,
    std] of every trial field in ``fields``, then ``extra(trials of the config) -> dict`` (optional),
    the successes, the trials with positive clearance (``min_clearance_m > 0``), the trial count and
    the MPC rate."""
    rows = []
    for name in configs:
        t = [x for x in trials if x["config"] == name]
        row = {"config": name, **{f: mean_std([x[f] for x in t]) for f in fields}, **(extra(t) if extra else {})}
        row.update(
            successes=int(sum(x["success"] for x in t)),
            positive_clearance=int(sum(x["min_clearance_m"] > 0 for x in t)),
            trials=len(t),
            steps_per_s=mean_std([x["steps_per_s"] for x in t]),
        )
        rows.append(row)
    return rows


def write_atomic(path: Path, text: str) -> None:
    """Write a text file atomically (temp file in the same folder, then rename)."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    tmp.replace(path)


def make_queries(
    means: np.ndarray,  # (N, 3) splat means, scene units
    lo: np.ndarray,  # (3,) lower corner of the scene bounds
    hi: np.ndarray,  # (3,) upper corner
    b: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """(b, 3) float64 query centres of the throughput benchmarks (E2 and ``benchmarks/metric_throughput.py``).

    Half uniform in the bounds, half uniform in a ball of radius 0.05 around a random splat mean.
    """
    u = rng.uniform(lo, hi, (b // 2, 3))
    d = rng.normal(size=(b - b // 2, 3))
    d *= (0.05 * rng.uniform(0, 1, (len(d), 1)) ** (1 / 3)) / np.linalg.norm(d, axis=1, keepdims=True)
    return np.concatenate([u, means[rng.integers(0, len(means), len(d))] + d])


def progress(iterable=None, **kw):
    """A tqdm progress bar on stderr when it is a terminal (SPLATPLAN_NO_TQDM=1 hides it there too)."""
    from tqdm import tqdm

    kw.setdefault("file", sys.stderr)
    kw.setdefault("leave", False)
    kw.setdefault("dynamic_ncols", True)
    kw.setdefault("disable", bool(os.environ.get("SPLATPLAN_NO_TQDM")) or not sys.stderr.isatty())
    return tqdm(iterable, **kw)
