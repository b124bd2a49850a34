"""Shared helpers of the studies (E1 precision-recall and E2 throughput first of all).

Units and frames: normalised scene units of the built-in Stonehenge (z up, ground top at z = 0,
x, y in [-0.5, 0.5]); robot = the sphere :data:`~splatplan.robots.DEFAULT_POINT_ROBOT` (r = 0.015 scene units).
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._warp import cpu_threads
from ..errors import SplatplanError
from ..scenes.filters import FilterReport, filter_floaters
from ..scenes.splats import Splats

if TYPE_CHECKING:
    from ..scenes.builtin.analytic_scene import AnalyticScene

#: Display names, in the order rows are printed.
DISPLAY = {
    "splatnav": "Splat-Nav",
    "safersplat": "SAFER-Splat",
    "atlasnav": "ATLASNav",
    "splanning": "SPLANNING",
    "collisionsplatting": "CollisionSplatting",
}


@contextmanager
def set_torch_threads(n: int | None = None):
    """Let torch use ``n`` intra-op threads inside the block (default: every core this process may
    use, :func:`splatplan._warp.cpu_threads`); the previous count is restored on exit. Yields ``n``."""
    import torch

    n = cpu_threads() if n is None else max(1, int(n))
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield n
    finally:
        torch.set_num_threads(before)


def load_stonehenge_filtered(level: int = 1, seed: int = 0, n_splats: int | None = None):
    """The built-in Stonehenge with floaters filtered (as the paper does).

    Returns:
        (splats, analytic_scene, filter_report).
    """
    from ..scenes.builtin.stonehenge import build_stonehenge

    splats, scene = build_stonehenge(level=level, seed=seed, n_splats=n_splats)
    splats, rep = filter_floaters(splats)
    return splats, scene, rep


def load_scene_with_gt(path: str | Path, gt: str | Path | None, filtered: bool = True) -> tuple[Splats, AnalyticScene, FilterReport | None]:
    """A splat file and its analytic ground truth (``.gt.json`` written by ``splatplan scene``).

    Args:
        path: the splat file.
        gt: its ground truth.
        filtered: drop floaters with the default rule (the report is None when False).

    Raises:
        SplatplanError: no ``gt`` given or a file is missing.
    """
    from ..scenes.load import load_scene
    from ..scenes.builtin.analytic_scene import AnalyticScene

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
