"""`splatplan eval STUDY`: the paper's studies (one nested subcommand per study).

Every study is ``run_<study>(out_dir, config=..., device=...)`` plus ``report(result) -> markdown``;
every field of its config dataclass is a flag here (``--quick`` starts from the config's
``quick()`` values, flags override either). When a study is done its markdown table is printed.
"""

from __future__ import annotations

import importlib

from ._common import _out_dir, add_config_args, add_device_arg, add_engine_args, config_from_args, engine_from_args

#: studies whose tasks run on the job engine (--workers N / --scheduler ADDR); `eval mbm` (registered
#: on its own, see :func:`register`) runs on it too
ENGINE_STUDIES = ("pr", "conservatism")

#: study -> (help, module under splatplan.eval, config class, run function, output files)
STUDIES = {
    "pr": ("E1 precision-recall against the four baselines (paper Fig. 3)", "pr", "PRConfig", "run_pr", ("pr.json", "pr.md", "pr.png")),
    "throughput": ("E2 checks/s and memory of every method (paper Table I)", "throughput", "ThroughputConfig", "run_throughput", ("throughput.json", "throughput.md")),
    "conservatism": (
        "E3 path length / clearance vs n_sigma (paper Table II, Fig. 4)", "conservatism", "ConservatismConfig", "run_conservatism",
        ("conservatism.json", "conservatism.md", "fig4_paths.png"),
    ),  # fmt: skip
    "linearization": (
        "E4 scenes M1..M5 of growing splat size (paper Table III, Fig. 5)", "linearization", "LinearizationConfig", "run_linearization",
        ("linearization.json", "linearization.md", "fig5_metric_along_path.png"),
    ),  # fmt: skip
}


def _study(name: str):
    _, mod, cfg_name, run_name, files = STUDIES[name]
    m = importlib.import_module(f"splatplan.eval.{mod}")
    return m, getattr(m, cfg_name), getattr(m, run_name), files


def cmd_eval(args) -> int:
    mod, cfg_cls, run, files = _study(args.study)
    engine = engine_from_args(args) if args.study in ENGINE_STUDIES else None
    base = cfg_cls.quick() if args.quick else cfg_cls()
    cfg = config_from_args(args, cfg_cls, base=base)
    if hasattr(cfg, "validate"):
        cfg.validate()
    out = _out_dir(args.out)
    kw = {"scene": args.scene, "gt": args.gt} if args.study == "pr" else {}
    if args.study in ENGINE_STUDIES:
        kw["engine"] = engine
    res = run(out, quick=args.quick, config=cfg, device=args.device, **kw)
    print(mod.report(res).rstrip())
    print(f"\nwrote {', '.join(str(out / f) for f in files)}")
    return 0


def cmd_mbm(args) -> int:
    """``splatplan eval mbm``: the MotionBenchMaker benchmark on splats (see splatplan.eval.mbm)."""
    from ..eval.mbm import MBMConfig, report, run_mbm

    engine = engine_from_args(args)
    base = MBMConfig.quick() if args.quick else MBMConfig()
    cfg = config_from_args(args, MBMConfig, base=base).validate()
    out = _out_dir(args.out)
    res = run_mbm(cfg, out, engine=engine)
    print(report(res).rstrip())
    print(f"\nwrote {out / 'mbm.json'}, {out / 'mbm.md'}, {out / 'mbm.results.jsonl'}")
    return 0


def register(sub, eval_sub) -> None:
    from ..eval.mbm import MBMConfig

    s = eval_sub.add_parser("mbm", help="MotionBenchMaker arm problems planned on splats of their scenes (writes mbm.json, mbm.md)",
                            description="MotionBenchMaker (MBM) Panda problems: MoveIt scenes sampled into splats, planned with each of --planners (default: ours; ompl:NAME for OMPL's), paths checked against the exact primitives; serial, or on Dask with --workers / --scheduler (results stream to OUT/mbm.results.jsonl; a rerun resumes).")  # fmt: skip
    s.add_argument("--out", required=True, help="output folder (created)")
    s.add_argument("--quick", action="store_true", help="start from the CI settings (1 problem per family, 30k splats, 5 s); flags still override them")
    add_engine_args(s)
    add_config_args(s, MBMConfig, group="benchmark options (MBMConfig)")
    s.set_defaults(func=cmd_mbm)
    for name, (help_, *_rest) in STUDIES.items():
        mod, cfg_cls, _, _ = _study(name)
        s = eval_sub.add_parser(name, help=help_, description=(mod.__doc__ or help_).strip().splitlines()[0])
        s.add_argument("--out", required=True, help="output folder (created)")
        s.add_argument("--quick", action="store_true", help="start from the small smoke-test settings (< 1 min); flags still override them")
        if name == "pr":
            s.add_argument("--scene", default="stonehenge", help="'stonehenge' (built-in) or a splat file with --gt")
            s.add_argument("--gt", help="ground-truth .gt.json of a scene file (written by 'splatplan scene')")
        add_device_arg(s)
        if name in ENGINE_STUDIES:
            add_engine_args(s)
        add_config_args(s, cfg_cls, group=f"study options ({cfg_cls.__name__})")
        s.set_defaults(func=cmd_eval, study=name)
