"""VAMP (KavrakiLab's SIMD RRT-Connect, the field's fastest CPU planner) on the same MotionBenchMaker
problems as splatplan, in the same run: a comparator for ``benchmarks/mbm_speed.py``, never a
dependency of the package.

VAMP comes as a wheel (``../shared/vendor/vamp/``, CPython 3.11, x86-64 with AVX2, robots sphere and
panda). :func:`vamp_python` installs it into a throw-away venv (``build/vamp-venv``, git-ignored) and
:func:`solve_vamp` runs ``benchmarks/_vamp_worker.py`` with that venv's python in a subprocess (JSON
in on stdin, JSON out through a temp file; VAMP's prints go to the captured stderr). This module
imports nothing from VAMP, and nothing here raises where VAMP is missing: ``vamp_python`` returns
``(None, reason)``, so a caller can skip the comparison with that reason.

    python benchmarks/vamp_compare.py --families box --n 3 --mode exact
    python benchmarks/vamp_compare.py --families table_pick,box,bookshelf_small --n 10 --mode capt

What is measured (see ``_vamp_worker.py`` for the conversions):

* ``plan_s``: VAMP's own planning time (``PlanningResult.nanoseconds``; RRT-Connect with the settings
  of ``vamp.configure_robot_and_planner_with_kwargs("panda", "rrtc")``, Halton sampler reset and
  skipped ``seed`` draws per problem, as VAMP's ``scripts/evaluate_mbm.py``);
* ``simplify_s``: VAMP's path simplification (``panda.simplify``, default settings: shortcut +
  B-spline), as VAMP users run it;
* ``path``: the **simplified** path's waypoints, NOT interpolated to VAMP's collision-check
  resolution (VAMP validates each segment internally at ``panda.resolution()`` = 32 steps per unit
  of configuration distance); its first and last waypoints are set to the float64 ``q_start`` /
  ``q_goal`` (VAMP works in float32);
* ``build_s``: CAPT build time (mode "capt"), VAMP's own count.

Robot model: VAMP's ``panda`` is its own 59-sphere model of the MBM Panda (tight, not covering:
../shared/vendor/vamp/README.md), not our certified ellipsoids. Scene: mode "exact" gives VAMP the
scene's boxes and spheres exactly; VAMP has no true cylinder, so a cylinder becomes a capsule (or a
box in family ``box``: VAMP's own MBM convention, ``cylinders="vamp"``), both containing it. Mode
"capt" gives VAMP only the points (thinned to ``thin_m`` voxels), as a CAPT with the robot's
``min_max_radii()`` (recorded in each result as r_min, r_max).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
WORKER = Path(__file__).resolve().with_name("_vamp_worker.py")
WHEEL_NAME = "vamp_planner-0.6.4-cp311-cp311-linux_x86_64.whl"
#: environment variable overriding the wheel's path
WHEEL_ENV = "SPLATPLAN_VAMP_WHEEL"
#: the wheel's CPython version
WHEEL_PY = (3, 11)

__all__ = ["default_wheel", "load_problems", "solve_vamp", "thin_points", "vamp_python"]


def default_wheel() -> Path:
    """The wheel: ``$SPLATPLAN_VAMP_WHEEL`` or ``<repo>/../shared/vendor/vamp/<wheel>``."""
    w = os.environ.get(WHEEL_ENV)
    return Path(w).expanduser() if w else (REPO / ".." / "shared" / "vendor" / "vamp" / WHEEL_NAME).resolve()


def _cpu_has_avx2() -> tuple[bool, str]:
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return False, f"VAMP's wheel is built for x86-64, this machine is {platform.machine()}"
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return True, ""  # cannot tell: the import check decides
    if " avx2" not in flags:
        return False, "this CPU has no AVX2 (VAMP's wheel is built with -march=x86-64-v3)"
    return True, ""


def _base_python() -> str | None:
    """A CPython 3.11 to create the venv with (the wheel is cp311)."""
    if sys.version_info[:2] == WHEEL_PY:
        return sys.executable
    return shutil.which(f"python{WHEEL_PY[0]}.{WHEEL_PY[1]}")


def _run(cmd, timeout=600, **kw) -> tuple[int, str]:
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kw)
    except (OSError, subprocess.SubprocessError) as e:
        return -1, f"{type(e).__name__}: {e}"
    return p.returncode, (p.stdout + p.stderr)


def _tail(s: str, n: int = 300) -> str:
    s = " ".join(s.strip().split())
    return s if len(s) <= n else "..." + s[-n:]


def _check_import(py: str) -> tuple[bool, str]:
    rc, out = _run([py, "-c", "import vamp, numpy; assert vamp.panda.n_spheres() > 0; print('ok')"], timeout=120,
                   env=_clean_env())  # fmt: skip
    if rc == 0 and out.strip().endswith("ok"):
        return True, ""
    if rc in (-4, 132):  # SIGILL
        return False, "import vamp died of an illegal instruction (no AVX2?)"
    return False, f"import vamp failed (rc {rc}): {_tail(out)}"


def _clean_env() -> dict:
    """The environment for VAMP's python: without PYTHONPATH / PYTHONHOME of splatplan's."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTHONSTARTUP")}
    env["PYTHONNOUSERSITE"] = "1"
    return env


def _install(base: str, env_dir: Path, wheel: Path) -> str:
    """Create the venv and install the wheel; '' or the reason it failed."""
    py = env_dir / "bin" / "python"
    if not py.is_file():
        rc, out = _run([base, "-m", "venv", str(env_dir)], timeout=300)
        if rc != 0:
            return f"python -m venv {env_dir} failed: {_tail(out)}"
    pip = [str(py), "-m", "pip", "install", "--disable-pip-version-check", "--no-input", "-q"]
    rc, out = _run(pip + [str(wheel)], timeout=600, env=_clean_env())
    if rc == 0:
        return ""
    # no package index (offline): the wheel alone, numpy from splatplan's own environment (a .pth)
    rc2, out2 = _run(pip + ["--no-deps", str(wheel)], timeout=600, env=_clean_env())
    if rc2 != 0:
        return f"pip install {wheel.name} failed: {_tail(out)} / --no-deps: {_tail(out2)}"
    try:
        import numpy as _np

        rc3, site = _run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], timeout=60, env=_clean_env())
        if rc3 != 0:
            return f"cannot locate the venv's site-packages: {_tail(site)}"
        (Path(site.strip()) / "splatplan_numpy.pth").write_text(str(Path(_np.__file__).resolve().parents[1]) + "\n")
    except OSError as e:
        return f"pip install {wheel.name} failed ({_tail(out)}); linking numpy failed too: {e}"
    return ""


_CACHE: dict[str, tuple[str | None, str]] = {}


def vamp_python(env_dir: str = "build/vamp-venv") -> tuple[str | None, str]:
    """The python of a throw-away venv with VAMP installed (created once), or (None, reason).

    ``env_dir`` is relative to the repository root (absolute paths are used as given). The wheel is
    ``$SPLATPLAN_VAMP_WHEEL`` or ``../shared/vendor/vamp/vamp_planner-0.6.4-cp311-...whl`` beside the
    repository. Checks: the wheel exists, the CPU is x86-64 with AVX2, a CPython 3.11 exists, and
    ``import vamp`` works in the venv. Never raises: every failure is ``(None, reason)``.
    """
    try:
        d = Path(env_dir)
        d = d if d.is_absolute() else REPO / d
        key = str(d)
        if key in _CACHE and _CACHE[key][0] is not None:
            return _CACHE[key]
        res = _vamp_python(d)
        _CACHE[key] = res
        return res
    except Exception as e:  # never raise
        return None, f"VAMP setup failed: {type(e).__name__}: {e}"


def _vamp_python(d: Path) -> tuple[str | None, str]:
    ok, why = _cpu_has_avx2()
    if not ok:
        return None, why
    py = d / "bin" / "python"
    stamp = d / ".splatplan-vamp-wheel"
    wheel = default_wheel()
    want = f"{wheel}:{wheel.stat().st_size}" if wheel.is_file() else None
    if py.is_file() and (want is None or (stamp.is_file() and stamp.read_text() == want)):
        good, why = _check_import(str(py))
        if good:
            return str(py), ""
    if want is None:
        return None, f"VAMP wheel not found at {wheel} (set {WHEEL_ENV})"
    base = _base_python()
    if base is None:
        return None, f"no CPython {WHEEL_PY[0]}.{WHEEL_PY[1]} to create the venv with (the wheel is cp311)"
    d.parent.mkdir(parents=True, exist_ok=True)
    import fcntl

    with open(str(d) + ".lock", "w") as lock:  # two processes never build the venv at once
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not (py.is_file() and stamp.is_file() and stamp.read_text() == want and _check_import(str(py))[0]):
                why = _install(base, d, wheel)
                if why:
                    return None, why
                good, why = _check_import(str(py))
                if not good:
                    return None, why
                stamp.write_text(want)
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return str(py), ""


def thin_points(points, voxel: float) -> np.ndarray:
    """One point per ``voxel``-sized cell of a grid anchored at the origin: of the points in a cell,
    the one nearest the cell's centre (ties: the lowest input index). Deterministic; the result is
    sorted by cell (x, then y, then z index), so it does not depend on the input's order except for
    exact ties. ``voxel <= 0`` returns a float64 copy. Returns (M, 3) float64."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if voxel is None or voxel <= 0 or len(p) == 0:
        return p.copy()
    cell = np.floor(p / voxel).astype(np.int64)
    d2 = (((cell + 0.5) * voxel - p) ** 2).sum(axis=1)
    order = np.lexsort((np.arange(len(p)), d2, cell[:, 2], cell[:, 1], cell[:, 0]))  # last key sorts first
    c = cell[order]
    first = np.ones(len(c), dtype=bool)
    first[1:] = np.any(c[1:] != c[:-1], axis=1)
    return p[order[first]]


def _problem_json(p: dict, mode: str, thin_m: float) -> tuple[dict, int]:
    objects = p.get("objects")
    if hasattr(objects, "to_json"):
        objects = objects.to_json()
    q = {"family": p.get("family"), "index": p.get("index"), "objects": objects,
         "q_start": [float(v) for v in np.asarray(p["q_start"]).reshape(-1)],
         "q_goal": [float(v) for v in np.asarray(p["q_goal"]).reshape(-1)]}  # fmt: skip
    n_raw = 0
    if mode == "capt":
        pts = p.get("points")
        if pts is not None:
            pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
            n_raw = len(pts)
            q["points"] = thin_points(pts, thin_m).tolist()
    return q, n_raw


def solve_vamp(python: str, problems: list[dict], mode: str = "exact", *, point_radius: float = 0.0025, thin_m: float = 0.02,
               seed: int = 0, timeout_s: float = 600, cylinders: str = "vamp", warmup: bool = True,
               meta: dict | None = None) -> list[dict]:  # fmt: skip
    """Solve ``problems`` with VAMP (RRT-Connect + simplification) in a subprocess run by ``python``
    (from :func:`vamp_python`).

    Each problem: ``{"family", "index", "objects": AnalyticScene.to_json() (or the scene itself),
    "q_start": (7,), "q_goal": (7,), "points": (N, 3) metres (mode "capt" only)}``. Mode "exact":
    the primitives (see the module docstring for cylinders); mode "capt": only the points, thinned
    to one per ``thin_m`` voxel (:func:`thin_points`; 0 = all), as a CAPT of ``point_radius`` points.
    ``warmup``: solve the first problem once, untimed, before the timed runs.

    Returns one dict per problem, in order: ``family, index, solved, plan_s, simplify_s, path``
    (simplified waypoints, list of 7-lists, not interpolated; None when unsolved), ``build_s`` (CAPT
    build, 0 in mode exact), ``n_points`` (points VAMP got), ``n_points_raw`` (before thinning),
    ``start_valid`` / ``goal_valid`` (VAMP's own check; an invalid endpoint is not planned),
    ``iterations``, ``n_waypoints_raw``, ``path_valid_vamp``, ``error`` ('' or why unsolved), and in
    mode capt ``r_min, r_max, point_radius``; in mode exact the counts ``cuboids, capsules, spheres``
    VAMP got. ``meta`` (a dict, optional) is filled with the run's settings (VAMP version, planner
    settings, r_min / r_max, ...).

    Raises RuntimeError when the worker fails as a whole (crash, timeout, unreadable output).
    """
    if not python:
        raise ValueError("solve_vamp: no VAMP python (vamp_python() returned None: skip the comparison with its reason)")
    if mode not in ("exact", "capt"):
        raise ValueError(f"mode {mode!r}: use 'exact' or 'capt'")
    if cylinders not in ("vamp", "capsule", "cuboid"):
        raise ValueError(f"cylinders {cylinders!r}: use 'vamp', 'capsule' or 'cuboid'")
    probs, raw = [], []
    t0 = time.perf_counter()
    for p in problems:
        q, n_raw = _problem_json(p, mode, thin_m)
        probs.append(q)
        raw.append(n_raw)
    thin_s = time.perf_counter() - t0
    job = {"mode": mode, "point_radius": float(point_radius), "seed": int(seed), "cylinders": cylinders, "warmup": bool(warmup),
           "problems": probs}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="splatplan-vamp-") as tmp:
        out_path = Path(tmp) / "out.json"
        try:
            proc = subprocess.run([python, str(WORKER), str(out_path)], input=json.dumps(job), capture_output=True, text=True,
                                  timeout=timeout_s, env=_clean_env(), cwd=tmp)  # fmt: skip
        except subprocess.TimeoutExpired as e:
            raise RuntimeError(f"VAMP worker timed out after {timeout_s} s: {_tail(str(e.stderr or ''), 500)}") from None
        except OSError as e:
            raise RuntimeError(f"cannot run the VAMP worker with {python}: {e}") from None
        if proc.returncode != 0 or not out_path.is_file():
            raise RuntimeError(f"VAMP worker failed (rc {proc.returncode}): {_tail(proc.stderr, 800)}")
        try:
            data = json.loads(out_path.read_text())
        except (OSError, ValueError) as e:
            raise RuntimeError(f"VAMP worker wrote unreadable output: {e}") from None
    results = data["results"]
    if len(results) != len(problems):
        raise RuntimeError(f"VAMP worker returned {len(results)} results for {len(problems)} problems")
    for r, p, n_raw in zip(results, probs, raw):
        r["n_points_raw"] = n_raw
        r.setdefault("build_s", 0.0)
        if r.get("path"):  # VAMP's float32 endpoints -> the exact float64 ones
            path = r["path"]
            for i, q in ((0, p["q_start"]), (-1, p["q_goal"])):
                if np.allclose(path[i], q, atol=1e-5, rtol=0):
                    path[i] = list(q)
                else:
                    r["error"] = (r.get("error") or "") + f" path endpoint {i} differs from the request by {np.abs(np.subtract(path[i], q)).max():.3g}"
    if meta is not None:
        meta.update(data.get("meta", {}))
        meta["thin_m"] = thin_m
        meta["thin_s"] = thin_s
        meta["worker_stderr_tail"] = _tail(proc.stderr, 500)
    return results


# ---------------------------------------------------------------------------------------------
# standalone check
# ---------------------------------------------------------------------------------------------


def load_problems(families, n: int | None, robot=None, problems_dir: str | None = None) -> tuple[list[dict], object]:
    """MBM problems through splatplan.eval.mbm (list_tasks + check_inputs) as solve_vamp dicts.
    Returns (problems, robot)."""
    from splatplan.eval.mbm import MBMConfig, check_inputs, list_tasks
    from splatplan.robots import load_robot

    cfg = MBMConfig(families=tuple(families), n_per_family=n, problems=problems_dir)
    robot = robot if robot is not None else load_robot(cfg.robot_path())
    tasks = check_inputs(list_tasks(cfg), robot)
    return [{"family": t.family, "index": t.index, "objects": t.objects, "q_start": list(t.q_start), "q_goal": list(t.q_goal)}
            for t in tasks], robot  # fmt: skip


def scene_points(objects: dict, n_splats: int, seed: int = 0, drop_floaters: bool = True) -> np.ndarray:
    """(N, 3) splat means sampled from a scene (splatplan's real-capture look, build_moveit), the
    floaters dropped as splatplan.eval.mbm does (points for mode capt in the standalone check)."""
    from splatplan.scenes.builtin.primitives import AnalyticScene
    from splatplan.scenes.moveit import build_moveit

    splats, _ = build_moveit(AnalyticScene.from_json(objects), n_splats=n_splats, seed=seed)
    if drop_floaters:  # as splatplan.eval.mbm prepares a scene: the paper's rule, then isolated faint splats
        from splatplan.scenes.filters import filter_floaters, isolated_mask

        splats, _ = filter_floaters(splats)
        iso = isolated_mask(splats.means, splats.opacities)
        if iso.any():
            splats = splats.subset(~iso)
    return np.asarray(splats.means, dtype=np.float64)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description="VAMP on MotionBenchMaker problems (standalone check of benchmarks/vamp_compare.py)")
    ap.add_argument("--families", default="box", help="comma-separated MBM families (default: box)")
    ap.add_argument("--n", type=int, default=3, help="problems per family (the first N)")
    ap.add_argument("--mode", choices=("exact", "capt"), default="exact")
    ap.add_argument("--cylinders", choices=("vamp", "capsule", "cuboid"), default="vamp")
    ap.add_argument("--thin-m", type=float, default=0.02)
    ap.add_argument("--point-radius", type=float, default=0.0025)
    ap.add_argument("--n-splats", type=int, default=100_000, help="mode capt: splats sampled per scene (their means are the points)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--env-dir", default="build/vamp-venv")
    ap.add_argument("--problems", default=None, help="MBM problems folder (default: ../shared/data/mbm/problems)")
    ap.add_argument("--json", default=None, help="write the results (paths included) to this JSON file")
    args = ap.parse_args(argv)

    py, why = vamp_python(args.env_dir)
    if py is None:
        print(f"VAMP unavailable: {why}")
        return {"skipped": why}
    problems, _ = load_problems(args.families.split(","), args.n, problems_dir=args.problems)
    if args.mode == "capt":
        for p in problems:
            p["points"] = scene_points(p["objects"], args.n_splats, args.seed)
    meta: dict = {}
    res = solve_vamp(py, problems, args.mode, point_radius=args.point_radius, thin_m=args.thin_m, seed=args.seed,
                     cylinders=args.cylinders, meta=meta)  # fmt: skip
    print(f"VAMP {meta.get('vamp_version')} rrtc, mode {args.mode}" + (f", cylinders {args.cylinders}" if args.mode == "exact" else
          f", r_min {meta.get('r_min'):.3f} r_max {meta.get('r_max'):.3f} point radius {args.point_radius} thinned to {args.thin_m} m"))  # fmt: skip
    head = f"{'family':<16} {'index':>5} {'start':>5} {'goal':>5} {'solved':>6} {'plan µs':>9} {'simplify µs':>11}"
    if args.mode == "capt":
        head += f" {'points':>7} {'build ms':>8}"
    print(head)
    for r in res:
        us = lambda v: f"{v * 1e6:.0f}" if v is not None else "-"  # noqa: E731
        line = (f"{r['family']:<16} {r['index']:>5} {str(r.get('start_valid', '-')):>5} {str(r.get('goal_valid', '-')):>5} "
                f"{str(r['solved']):>6} {us(r['plan_s']):>9} {us(r['simplify_s']):>11}")  # fmt: skip
        if args.mode == "capt":
            line += f" {r['n_points']:>7} {r['build_s'] * 1e3:>8.2f}"
        print(line + (f"  {r['error']}" if r.get("error") else ""))
    sol = [r for r in res if r["solved"]]
    med = lambda k: float(np.median([r[k] for r in sol])) if sol else float("nan")  # noqa: E731
    summ = {"solved": len(sol), "n": len(res), "median_plan_s": med("plan_s"), "median_simplify_s": med("simplify_s"),
            "median_build_s": med("build_s")}  # fmt: skip
    print(f"solved {len(sol)}/{len(res)}; median plan {summ['median_plan_s'] * 1e6:.0f} µs, simplify {summ['median_simplify_s'] * 1e6:.0f} µs"
          + (f", CAPT build {summ['median_build_s'] * 1e3:.2f} ms" if args.mode == "capt" else ""))  # fmt: skip
    if args.json:
        Path(args.json).write_text(json.dumps({"meta": meta, "summary": summ, "results": res}, indent=1))
    return summ


if __name__ == "__main__":
    main()
