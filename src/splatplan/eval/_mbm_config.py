"""MotionBenchMaker benchmark: its settings (:class:`MBMConfig`), a task, a result and the data folder.

See :mod:`splatplan.eval.mbm` for what the benchmark measures.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .._config import bounded, check_config
from ..errors import SplatplanError

__all__ = ["DEFAULT_MBM", "MBM_DATA_ENV", "PUBLISHED", "MBMConfig", "MBMResult", "MBMTask", "check_planners", "mbm_data_dir"]

#: the repository root (src/splatplan/eval/_mbm_config.py -> 3 levels up); shared data lives beside it
_REPO = Path(__file__).resolve().parents[3]
#: environment variable naming the MBM data folder (``problems/`` + ``panda/``) when --problems /
#: --robot are not given
MBM_DATA_ENV = "SPLATPLAN_MBM_DATA"
DEFAULT_MBM = _REPO / ".." / "shared" / "data" / "mbm"  # a source checkout's sibling data folder


def mbm_data_dir() -> Path:
    """The MBM data folder: ``$SPLATPLAN_MBM_DATA``, else the source checkout's ``../shared/data/mbm``
    (an installed package has none: then give --problems and --robot, or set the variable)."""
    env = os.environ.get(MBM_DATA_ENV, "").strip()
    return Path(env) if env else DEFAULT_MBM

#: Published reference numbers (../shared/data/mbm/README.md): same 700 problems, 7 families.
PUBLISHED: dict[str, dict[str, Any]] = {
    "VAMP": {
        "solved": "699/700 (99.86%)", "median_time_s": 35e-6, "mean_time_s": 76e-6, "p95_time_s": 343e-6,
        "robot_model": "59 spheres (0.90x the mesh volume, 26-73% of each link's surface covered)",
        "scene": "exact primitives (also a point cloud via CAPT: median 111 us + 2-7 ms to build)",
        "hardware": "one core of an AMD Ryzen 9 7950X (SIMD RRT-Connect)",
    },
    "cuRobo v2": {
        "solved": "99.73%", "median_time_s": 35e-3, "mean_time_s": None, "p95_time_s": None,
        "robot_model": "spheres", "scene": "exact primitives (MBM + MpiNets problems)",
        "hardware": "GPU, NVIDIA RTX 6000 Ada",
    },
}  # fmt: skip


@dataclass
class MBMConfig:
    """Knobs of the MBM benchmark (defaults = the full run; :meth:`quick` = the CI smoke version)."""

    #: folder holding <family>_panda/sceneNNNN.yaml + requestNNNN.yaml; none = <repo>/../shared/data/mbm/problems
    problems: str | None = None
    #: families to run (folder names without the "_panda" suffix)
    families: tuple[str, ...] = ("table_pick", "box", "bookshelf_small")
    #: problems per family (the first N by index); none = all
    n_per_family: int | None = bounded(None, ge=1)
    #: metric conservatism of the planner's collision checks (0 = splat means, the default: with the
    #: derived margin the least conservative safe setting; see the module docstring)
    n_sigma: float = bounded(0.0, ge=0)
    #: surface sampling spacing of each scene (m; the built-in real-capture look): a scene gets
    #: (exposed area / spacing^2) splats (scenes.builtin.surface_splats.n_splats_for_spacing), so a
    #: large cell is sampled as densely as a small one. The safety margin is ~3.4x the splats'
    #: median nearest-neighbour spacing h (~0.6x this): 3.5 mm gives h ~ 2.2 mm and a ~7.6 mm margin,
    #: below the ~1 cm between a grasp pose's fingers and its object (on the MBM workcells, 5.7-6.5
    #: m^2 of surface: 480-560k splats; a real capture of such a cell has 0.3-3M). At 100k splats
    #: (h ~ 5 mm, margin ~16 mm) most grasp goals cannot be called free
    splat_spacing_m: float = bounded(3.5e-3, gt=0, le=1.0)
    #: a fixed splat count per scene instead (none = from splat_spacing_m)
    n_splats: int | None = bounded(None, ge=1000)
    #: most splats per scene from splat_spacing_m (a larger scene is sampled more coarsely; each
    #: row records its count and spacing, and the derived margin follows the coarser spacing)
    max_splats: int = bounded(3_000_000, ge=1000)
    #: after the paper's floater filter, also drop the faint isolated splats it keeps
    #: (:func:`~splatplan.scenes.filters.isolated_mask`: opacity < 0.3 and a mean 8-NN distance above
    #: 3x the scene's median; surfaces are dense and opaque splats are never dropped, so the margin's
    #: covering argument is untouched). Real captures and the sampler's look both carry such floaters
    #: in free space, and the denser the scene, the more of them stand in a robot's way
    drop_isolated: bool = True
    #: planning time limit per problem (s)
    time_limit: float = bounded(10.0, gt=0)
    #: robot URDF (or a built-in name, e.g. panda); none = <repo>/../shared/data/mbm/panda/panda.urdf
    robot: str | None = None
    #: planning margin (m) added around every ellipsoid (Robot.inflated); none = derived per scene
    #: from the splats and n_sigma (see margin_spacing_factor); 0 = plan with the robot's own model
    margin_m: float | None = bounded(None, ge=0)
    #: derived margin = max(this x h - n_sigma x s_t, margin_floor_factor x h) + r/2, h = median
    #: nearest-neighbour distance of the splat means, s_t = median middle std of the splats (the
    #: sampler's covering radius measured 2.3-2.6 h at n_sigma 0: 3 keeps the bound with room)
    margin_spacing_factor: float = bounded(3.0, ge=0)
    #: the derived margin's estimate of the covering radius never drops below this x h, whatever
    #: n_sigma (the splats' offsets along the surface normal are not covered by their tangential extent)
    margin_floor_factor: float = bounded(0.5, ge=0)
    #: leave an endpoint the margin blocks by a short segment checked at a finer resolution with the
    #: smaller margin that keeps the same guarantee (splatplan.planners.escape; our planners, derived
    #: or given margin > 0); false: such a problem is not started
    endpoint_escape: bool = True
    #: ellipsoid YAML of a tighter model of the robot for the escape segments' finer check (a fit of
    #: the same URDF whose ellipsoids still contain every link): "builtin" = the shipped model of
    #: MBM's Panda with 10 ellipsoids on each wrist and hand link (reach 4 mm; panda_link5: 16, 2 mm;
    #: used when the robot is MBM's Panda URDF, by content); none = the planning model. The escape configuration is checked with the planning model
    escape_ellipsoids: str | None = "builtin"
    #: measure the true covering radius rho(n_sigma) from the ground truth (diagnostic: did
    #: m >= rho + r/2 hold? ~1 s per scene at n_sigma 0, tens of seconds above; off by default)
    check_margin: bool = False
    #: iteration budget of our planners' searches (reproducible benchmark mode: the search and
    #: shortcut then run without a wall-clock limit, so no row depends on the machine's speed; the
    #: summary counts solutions slower than time_limit as solved_late); none = time_limit ends the search
    max_iters: int | None = bounded(None, ge=1)
    #: scene sampling and planner seed (an integer >= 0)
    seed: int = bounded(0, ge=0)
    #: planners to compare, each on the same checker, time limit and margin: auto / rrt / rrtconnect
    #: (ours, seeded) or ompl:NAME (an OMPL geometric planner, e.g. ompl:RRTConnect, ompl:BITstar,
    #: ompl:PRM; the 'ompl' extra; not seedable)
    planners: tuple[str, ...] = ("auto",)

    @classmethod
    def quick(cls) -> "MBMConfig":
        """One problem per family at the full run's splat spacing, 5 s limit: the CI smoke version
        (< ~20 s). At a fixed 30k splats the derived margin (~3 cm) leaves no grasp goal free, so
        nothing would be planned."""
        return cls(n_per_family=1, time_limit=5.0)

    def validate(self) -> "MBMConfig":
        check_config(self)  # every field's range and finiteness (named Class.field)
        if not self.families:
            raise SplatplanError("MBMConfig.families: give at least one family")
        check_planners(self.planners)
        return self

    def problems_dir(self) -> Path:
        d = Path(self.problems) if self.problems else mbm_data_dir() / "problems"
        if not d.is_dir():
            how = "" if self.problems else f" (the default: ${MBM_DATA_ENV}/problems, else the source checkout's ../shared/data/mbm)"
            raise SplatplanError(f"MBM problems folder {d} not found{how}: pass --problems DIR (holding <family>_panda/sceneNNNN.yaml + "
                                 f"requestNNNN.yaml) or set {MBM_DATA_ENV}")  # fmt: skip
        return d

    def robot_path(self) -> Path | str:
        """The URDF path (or a built-in robot name such as "panda")."""
        from ..robots import KNOWN

        if self.robot in KNOWN:
            return self.robot
        p = Path(self.robot) if self.robot else mbm_data_dir() / "panda" / "panda.urdf"
        if not p.is_file():
            raise SplatplanError(f"robot URDF {p} not found: pass --robot URDF" + ("" if self.robot else f" or set {MBM_DATA_ENV}"))
        return p


def check_planners(names) -> tuple[str, ...]:
    """Validate planner names (ours, or ``ompl:NAME`` with the extra installed and NAME one of
    OMPL's geometric planners); a one-line :class:`SplatplanError` otherwise."""
    from ..planners import PLANNERS

    names = tuple(names)
    if not names:
        raise SplatplanError("MBMConfig.planners: give at least one planner (e.g. auto,ompl:RRTConnect)")
    if len(set(names)) != len(names):
        raise SplatplanError(f"MBMConfig.planners: a planner is listed twice in {','.join(names)}")
    for n in names:
        if n in PLANNERS:
            continue
        if not n.startswith("ompl:"):
            raise SplatplanError(f"MBMConfig.planners: unknown planner {n!r}: use {', '.join(PLANNERS)} or ompl:NAME (e.g. ompl:RRTConnect)")
        from ..planners.ompl_bridge import available_planners  # the install hint when the extra is missing

        have = available_planners()
        if n[5:] not in have:
            raise SplatplanError(f"MBMConfig.planners: unknown OMPL planner {n[5:]!r}: available: {', '.join(have)}")
    return names


@dataclass(frozen=True)
class MBMTask:
    """One (problem, planner): what a worker needs to solve it (plain data, picklable, JSON-able).

    ``objects`` (the parsed scene, :meth:`AnalyticScene.to_json`) and ``q_start`` / ``q_goal`` come
    from :func:`check_inputs`, which parses every YAML once before the run, so the workers never
    parse them again; without them (a task built by hand) the worker reads the files."""

    family: str
    index: int
    scene: str  # path of sceneNNNN.yaml
    request: str  # path of requestNNNN.yaml
    planner: str = "auto"  # a name of MBMConfig.planners
    objects: dict | None = None  # the parsed scene (AnalyticScene.to_json), or None
    q_start: tuple[float, ...] | None = None  # (dof,) from the request, or None
    q_goal: tuple[float, ...] | None = None  # (dof,)



@dataclass
class MBMResult:
    """Rows, per-family and overall summaries, and what was run."""

    config: MBMConfig
    rows: list[dict]  # one per (problem, planner) that finished, problem-major
    summary: dict[str, dict]  # family / "overall" -> summary, of the first planner (ours by default)
    setup: dict = field(default_factory=dict)
    time_s: float = 0.0
    summary_by_planner: dict[str, dict] = field(default_factory=dict)  # planner -> family -> summary
    failures: list[dict] = field(default_factory=list)  # tasks recorded as failed, with their error

    def to_json(self) -> dict:
        return {"study": "mbm", "config": asdict(self.config), "engine": self.setup.get("engine", {"kind": "serial"}), "setup": self.setup,
                "summary": self.summary, "summary_by_planner": self.summary_by_planner, "rows": self.rows, "failures": self.failures,
                "published": PUBLISHED, "time_s": self.time_s}  # fmt: skip
