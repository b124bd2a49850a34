"""`splatplan sweep SPEC.yaml --out DIR`: a grid of plan or check jobs over many scene files.

The YAML schema is :class:`splatplan.eval.sweep.SweepSpec` (its module docstring has an example).
``--workers N`` runs the grid on a local Dask cluster, ``--scheduler ADDR`` on an existing one;
a rerun into the same ``--out`` skips the cells already in ``results.jsonl``. Exit codes: 0 every
cell ran (planning failures are results, not errors), 1 some cells raised (recorded with their
error in results.jsonl), 2 bad input.
"""

from __future__ import annotations

import sys

from ._flags import add_command, add_engine_args, engine_from_args
from ._outputs import out_dir


def cmd_sweep(args) -> int:
    from ..eval.sweep import load_spec, report, run_sweep

    engine = engine_from_args(args)
    spec, base = load_spec(args.spec)
    out = out_dir(args.out)
    summary = run_sweep(spec, base, out, engine=engine)
    print(report(summary).rstrip())
    print(f"\nwrote {out / 'results.jsonl'}, {out / 'summary.json'}, {out / 'summary.md'}")
    if summary["n_failed"]:
        first = next(iter(summary["errors"].items()))
        print(f"splatplan: {summary['n_failed']} task(s) failed, e.g. {first[0]}: {first[1]}", file=sys.stderr)
        return 1
    return 0


def register(sub, eval_sub) -> None:
    s = add_command(sub, "sweep", cmd_sweep, "a grid of plan or check jobs over many scene files (serial, or on Dask)",
                    "Run a grid of plan or check jobs (scenes x n_sigma x planners x pairs x seeds) described by a YAML spec; results "
                    "stream to DIR/results.jsonl and a rerun resumes. Exit codes: 0 done, 1 some tasks failed, 2 bad input.")  # fmt: skip
    s.add_argument("spec", metavar="SPEC.yaml", help="the sweep (keys: scenes, job, robot, n_sigma, seeds, planners, time_limit, max_iters, "
                   "refine, pairs, pair_seed, n_configs, filter_floaters, n_splats, device)")  # fmt: skip
    s.add_argument("--out", required=True, help="output folder (created; reused to resume)")
    add_engine_args(s)
