"""Scene loading: time and peak memory for a large INRIA ply (issue 7: 5M splats, SH degree 3).

Writes a synthetic INRIA 3DGS ply (``--n`` splats, SH degree ``--sh-degree``, float32 fields in
the usual exporter order, realistic value ranges) to a temporary folder, then measures, each in a
fresh Python process so that the peak resident set size (``VmHWM``) belongs to that one task:

* ``load_scene(path, filter_floaters=False)`` -- the decoder alone;
* ``load_scene(path)`` -- decoder + default floater filter;
* ``splatplan info path`` -- the CLI command of the issue;
* optionally (``--spz``) the same scene written as SPZ v4 and loaded;
* optionally (``--reference COMMIT``) the decoder of an older commit, for a before/after figure
  (skipped when the machine has too little free memory for it).

``rss_before`` is the resident size after the imports, just before loading; the issue's target
is a load peak of about 2x the file plus the output arrays. The ply (and spz) are deleted
afterwards.

    python benchmarks/scene_load.py [--n 5000000] [--sh-degree 3] [--spz] [--reference 9d73817]
                                    [--out benchmarks/results/scene_load.json]

Prints a markdown table and writes JSON (and scene_load.md next to it).
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
SH_DIM = {0: 0, 1: 3, 2: 8, 3: 15}
BLOCK = 1 << 18

#: Run in a child process: import, measure RSS, run the task, report time and VmHWM as JSON.
CHILD = r"""
import json, sys, time

def status(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    return -1

task, path = sys.argv[1], sys.argv[2]
if task == "cli_info":
    from splatplan.cli import main
    import splatplan.metric  # what `info` imports, so rss_before is comparable
else:
    from splatplan.scenes.load import load_scene
before = status("VmRSS")
t0 = time.perf_counter()
if task == "load_raw":
    s = load_scene(path, filter_floaters=False)
    n = len(s)
elif task == "load_filtered":
    s = load_scene(path)
    n = len(s)
elif task == "cli_info":
    import contextlib, io
    with contextlib.redirect_stdout(io.StringIO()):
        rc = main(["info", path])
    assert rc == 0, rc
    n = -1
dt = time.perf_counter() - t0
print(json.dumps({"time_s": dt, "rss_before": before, "vmhwm": status("VmHWM"), "n": n}))
"""


def write_synthetic_ply(path: Path, n: int, sh_degree: int, seed: int = 0) -> int:
    """Write an INRIA ply of n random splats block by block (memory: one block). Returns its size."""
    k = SH_DIM[sh_degree]
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"] + [f"f_rest_{i}" for i in range(3 * k)]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    dtype = np.dtype([(name, "<f4") for name in names])
    header = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n
    header += "".join(f"property float {name}\n" for name in names) + "end_header\n"
    rng = np.random.default_rng(seed)
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for a in range(0, n, BLOCK):
            m = min(BLOCK, n - a)
            rows = np.zeros(m, dtype=dtype)
            for ax in "xyz":
                rows[ax] = rng.normal(0.0, 2.0, m)  # a room-sized capture, scene units
            for c in range(3):
                rows[f"f_dc_{c}"] = rng.normal(0.0, 1.0, m)
            for i in range(3 * k):
                rows[f"f_rest_{i}"] = rng.normal(0.0, 0.1, m)
            rows["opacity"] = rng.normal(0.0, 3.0, m)  # logit
            for j in range(3):
                rows[f"scale_{j}"] = rng.uniform(-7.0, -3.0, m)  # log std
            for j in range(4):
                rows[f"rot_{j}"] = rng.normal(0.0, 1.0, m)
            f.write(rows.tobytes())
    return path.stat().st_size


def run_child(task: str, path: Path, pythonpath: Path | None = None) -> dict:
    env = dict(os.environ, SPLATPLAN_NO_TQDM="1")
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    res = subprocess.run([sys.executable, "-c", CHILD, task, str(path)], capture_output=True, text=True, env=env, cwd=REPO)
    if res.returncode != 0:
        raise RuntimeError(f"{task} failed:\n{res.stderr}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def mem_available() -> int:
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    return 0


def export_reference(commit: str, dest: Path) -> Path | None:
    """``src/`` of an older commit, extracted with ``git archive``, or None if that fails."""
    try:
        tar = subprocess.run(["git", "archive", commit, "src"], cwd=REPO, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(dest)], input=tar, check=True)
    except (subprocess.CalledProcessError, FileNotFoundError):
        return None
    return dest / "src"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=5_000_000, help="splats in the synthetic ply")
    ap.add_argument("--sh-degree", type=int, default=3, choices=[0, 1, 2, 3])
    ap.add_argument("--tasks", default="load_raw,load_filtered,cli_info", help="comma-separated subset of load_raw, load_filtered, cli_info")
    ap.add_argument("--spz", action="store_true", help="also write the scene as SPZ v4 and time loading it")
    ap.add_argument("--reference", default=None, help="also measure load_scene of this older commit (before/after)")
    ap.add_argument("--tmp", default=tempfile.gettempdir(), help="folder for the temporary files")
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "scene_load.json"))
    args = ap.parse_args(argv)

    work = Path(tempfile.mkdtemp(prefix="splatplan_scene_load_", dir=args.tmp))
    rows: list[dict] = []
    try:
        ply = work / "synthetic.ply"
        t0 = time.perf_counter()
        file_bytes = write_synthetic_ply(ply, args.n, args.sh_degree)
        print(f"wrote {ply} ({file_bytes / 1e9:.2f} GB) in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
        k = SH_DIM[args.sh_degree]
        out_bytes = args.n * (3 + 4 + 3 + 1 + 3 + 3 * k) * 4  # float32 Splats arrays

        def add(label: str, fmt: str, task: str, path: Path, size: int, **kw) -> None:
            load_avg = os.getloadavg()[0]
            r = run_child(task, path, **kw)
            load_peak = r["vmhwm"] - r["rss_before"]
            rows.append(
                {
                    "task": label,
                    "format": fmt,
                    "file_bytes": size,
                    "time_s": round(r["time_s"], 3),
                    "rss_before_bytes": r["rss_before"],
                    "peak_rss_bytes": r["vmhwm"],
                    "load_peak_bytes": load_peak,
                    "peak_over_file": round(r["vmhwm"] / size, 2),
                    "target_bytes": 2 * size + out_bytes,
                    "load_average_1min": round(load_avg, 2),
                }
            )
            print(f"{label}: {r['time_s']:.2f} s, peak RSS {r['vmhwm'] / 1e9:.2f} GB", file=sys.stderr)

        labels = {"load_raw": "load_scene(filter_floaters=False)", "load_filtered": "load_scene() (with floater filter)", "cli_info": "splatplan info"}
        for task in args.tasks.split(","):
            if task not in labels:
                ap.error(f"unknown task {task!r}; choose from {', '.join(labels)}")
            add(labels[task], "inria ply", task, ply, file_bytes)
        if args.spz:
            sys.path.insert(0, str(REPO / "src"))
            from splatplan.scenes.io_spz import write_spz
            from splatplan.scenes.load import load_scene

            spz = work / "synthetic.spz"
            write_spz(load_scene(ply, filter_floaters=False), spz)
            add("load_scene(filter_floaters=False)", "spz v4", "load_raw", spz, spz.stat().st_size)
        if args.reference:
            need = 7 * file_bytes
            if mem_available() < need + (2 << 30):
                print(f"skipping the reference {args.reference}: needs about {need / 1e9:.1f} GB free", file=sys.stderr)
            else:
                ref_src = export_reference(args.reference, work)
                if ref_src is not None:
                    add(f"load_scene(filter_floaters=False) @ {args.reference}", "inria ply", "load_raw", ply, file_bytes, pythonpath=ref_src)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    result = {
        "config": {"n": args.n, "sh_degree": args.sh_degree, "output_bytes": out_bytes, "block_rows": BLOCK},
        "machine": {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count()},
        "notes": (
            "peak_rss_bytes = VmHWM of a fresh process (interpreter and imports included); load_peak_bytes = "
            "VmHWM - VmRSS just before loading; target_bytes = 2 x file + float32 output arrays (issue 7). "
            "Times are wall-clock on a shared machine: load_average_1min (taken before each task) above the CPU "
            "count means other processes competed for the cores, and the time is inflated accordingly."
        ),
        "rows": rows,
    }
    gb = 1e9
    lines = [
        f"Scene loading, synthetic INRIA ply: {args.n:,} splats, SH degree {args.sh_degree} ({file_bytes / gb:.2f} GB file, "
        f"{out_bytes / gb:.2f} GB float32 output)",
        "",
        "| task | format | file (GB) | time (s) | load avg | peak RSS (GB) | peak / file | load peak above imports (GB) | target 2x file + output (GB) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['task']} | {r['format']} | {r['file_bytes'] / gb:.2f} | {r['time_s']:.2f} | {r['load_average_1min']:.1f} | {r['peak_rss_bytes'] / gb:.2f} | "
            f"{r['peak_over_file']:.2f} | {r['load_peak_bytes'] / gb:.2f} | {r['target_bytes'] / gb:.2f} |"
        )
    table = "\n".join(lines)
    print(table)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    out.with_suffix(".md").write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
