"""`splatplan eval STUDY`: the paper's studies (one nested subcommand per study).

Every study module exposes ``XConfig`` (a flat dataclass: every field is a flag here; ``--quick``
starts from ``XConfig.quick_config()`` and flags override either), ``run(config, engine=None) ->
XResult``, ``markdown(result)`` and ``report(result, out_dir) -> [paths written]``. When a study is
done its markdown table is printed.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, cast

from ._config_flags import Unset, add_config_args, config_from_args
from ._flags import add_engine_args, engine_from_args
from ._outputs import out_dir

if TYPE_CHECKING:
    from ..robots.robot import Robot

#: studies whose tasks run on the job engine (--workers N / --scheduler ADDR); finished tasks stream
#: to OUT/<study>.results.jsonl and a rerun resumes. `eval mbm` (registered on its own, see
#: :func:`register`) runs on it too
ENGINE_STUDIES = ("pr", "conservatism")

#: study -> (help, module under splatplan.eval, config class)
STUDIES = {
    "pr": ("E1 precision-recall against the four baselines (paper Fig. 3)", "pr", "PRConfig"),
    "throughput": ("E2 checks/s and memory of every method (paper Table I)", "throughput", "ThroughputConfig"),
    "conservatism": ("E3 path length / clearance vs n_sigma (paper Table II, Fig. 4)", "conservatism", "ConservatismConfig"),
    "linearization": ("E4 scenes M1..M5 of growing splat size (paper Table III, Fig. 5)", "linearization", "LinearizationConfig"),
}


def _study(name: str):
    """(module, config class) of study ``name``."""
    _, mod, cfg_name = STUDIES[name]
    m = importlib.import_module(f"splatplan.eval.{mod}")
    return m, getattr(m, cfg_name)


def cmd_eval(args) -> int:
    mod, cfg_cls = _study(args.study)
    engine = engine_from_args(args) if args.study in ENGINE_STUDIES else None
    base = cfg_cls.quick_config() if args.cfg_quick is True else cfg_cls()
    cfg = config_from_args(args, cfg_cls, base=base)  # validated
    out = out_dir(args.out)
    kw = {"engine": engine, "results": out / f"{args.study}.results.jsonl"} if args.study in ENGINE_STUDIES else {}
    res = mod.run(cfg, **kw)
    written = mod.report(res, out)
    print(mod.markdown(res).rstrip())
    print(f"\nwrote {', '.join(str(p) for p in written)}")
    return 0


def _mbm_joints_first(cfg) -> None:
    """Cheap checks before the fit (a URDF whose joints the problems do not name is
    rejected before a fit that can take minutes): a URDF robot's joint names against every problem's
    requests, from the URDF alone. Joint limits are checked later against the loaded robot."""
    from pathlib import Path
    from types import SimpleNamespace

    import numpy as np

    from ..eval.mbm import check_inputs, list_tasks
    from ..robots import KNOWN

    if cfg.robot is None or cfg.robot in KNOWN or Path(str(cfg.robot_path())).suffix.lower() != ".urdf":
        return
    from ..robots.urdf import read_urdf

    model = read_urdf(cfg.robot_path())
    n = len(model.dof_joints)
    stub = SimpleNamespace(name=model.name, joint_names=list(model.dof_joints), kin=model.kin,
                           joint_limits=np.tile([-np.inf, np.inf], (n, 1)))  # names only here
    check_inputs(list_tasks(cfg), cast("Robot", stub))  # (a stand-in: the joint names and limits the check reads)


def cmd_mbm(args) -> int:
    """``splatplan eval mbm``: the MotionBenchMaker benchmark on splats (see splatplan.eval.mbm)."""
    from ..eval.mbm import MBMConfig, report, run_mbm

    engine = engine_from_args(args)
    base = MBMConfig.quick() if args.quick else MBMConfig()
    cfg = config_from_args(args, MBMConfig, base=base).validate()
    _mbm_joints_first(cfg)
    out = out_dir(args.out)
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
        mod, cfg_cls = _study(name)
        s = eval_sub.add_parser(name, help=help_, description=(mod.__doc__ or help_).strip().splitlines()[0])
        s.add_argument("--out", required=True, help="output folder (created)")
        s.add_argument("--quick", dest="cfg_quick", action="store_const", const=True, default=Unset,
                       help="start from the small smoke-test settings (< 1 min); flags still override them")  # fmt: skip
        if name in ENGINE_STUDIES:
            add_engine_args(s)
        add_config_args(s, cfg_cls, skip=("quick",), group=f"study options ({cfg_cls.__name__})")
        s.set_defaults(func=cmd_eval, study=name)
