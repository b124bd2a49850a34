"""MPC rates of two source trees, alternating on one machine (issue #22: "MPC rates are not lower").

    python benchmarks/mpc_rates.py --before /path/to/old/checkout --after . [--rounds 2]

Each round runs ``splatplan mpc`` for the Panda (tabletop, 60 steps) and the Go2 (apartment, 40
steps) from each tree's ``src/`` with this interpreter, and reads ``steps_per_s`` from result.json.
The after tree also runs ``panda_like``: the built-in Panda as the before tree had it when that
tree predates the tight default (``--after-panda-like``, default the coarse one-per-link model at
collision stride 2), so a code change is compared apart from a model change.
Prints a table and writes ``benchmarks/results/mpc_rates.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

RUNS = {
    "panda": ["--robot", "panda", "--scene", "tabletop", "--goal-pose", "0.5,0.2,0.3,0,1,0,0", "--arm-max-steps", "60"],
    "go2": ["--robot", "go2", "--scene", "apartment", "--goal", "1.5,2.0", "--base-max-steps", "40"],
}


def run_once(tree: Path, args: list[str], out: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree / "src")}
    subprocess.run([sys.executable, "-m", "splatplan.cli", "mpc", *args, "--out", str(out)], env=env, check=False, capture_output=True, timeout=900)
    d = json.loads((out / "result.json").read_text())
    return {"steps_per_s": d["steps_per_s"], "success": d["success"], "min_clearance_m": d["min_clearance_m"], "n_steps": d["extra"]["n_steps"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, type=Path, help="checkout of the old code")
    ap.add_argument("--after", default=Path("."), type=Path, help="checkout of the new code (default: here)")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--after-panda-like", default="--robot panda:coarse --arm-collision-stride 2",
                    help="extra arguments of the after tree's panda_like run ('' = no such run)")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/mpc_rates.json"))
    args = ap.parse_args()
    runs = {("before", k): v for k, v in RUNS.items()} | {("after", k): v for k, v in RUNS.items()}
    if args.after_panda_like:
        runs[("after", "panda_like")] = [*RUNS["panda"], *args.after_panda_like.split()]  # later flags win
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for (label, robot), run_args in runs.items():
                tree = args.before if label == "before" else args.after
                res = run_once(tree.resolve(), run_args, Path(tmp) / f"{label}_{robot}_{r}")
                rows.append({"round": r, "tree": label, "robot": robot, "args": run_args, **res})
    print("| robot | tree | MPC steps/s (each round) | success | min clearance (m) | steps |")
    print("|---|---|---|---|---|---|")
    for robot in (*RUNS, "panda_like"):
        for label in ("before", "after"):
            rs = [x for x in rows if x["robot"] == robot and x["tree"] == label]
            if not rs:
                continue
            rates = ", ".join(format(x["steps_per_s"], ".1f") for x in rs)
            print(f"| {robot} | {label} | {rates} | {rs[0]['success']} | {rs[0]['min_clearance_m']:.4f} | {rs[0]['n_steps']} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"before": str(args.before), "after": str(args.after), "after_panda_like": args.after_panda_like, "load_avg": os.getloadavg(), "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
