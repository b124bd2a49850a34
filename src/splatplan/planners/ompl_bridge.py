"""OMPL's geometric planners (RRTConnect, RRTstar, BITstar, PRM, KPIECE1, ...) on splatplan's checker.

Optional: needs the ``ompl`` extra (``pip install 'splatplan[ompl]'``, OMPL 2.0.x wheels).

    from splatplan.planners.ompl_bridge import plan_ompl
    res = plan_ompl(checker, q_start, q_goal, robot=load_robot("panda"), name="BITstar", time_limit_s=5.0)
    res.success, res.path, res.length, res.info["ompl_status"]

**Same problem as our RRT.** The state space is the RRT's sampling box (:meth:`RRT.settings`: joint
limits, the robust scene box for translations, the given ``box_lo``/``box_hi``; coordinates with
lo == hi stay fixed at the start's value and are left out of OMPL's space). OMPL sees each free
coordinate scaled by the robot's ``motion_bound`` (``z = motion_bound * q``), so OMPL's Euclidean
distance (its ranges, its neighbourhoods, its path lengths) is our planners' configuration metric
in scene units.

**Same checker.** The state validity checker is ``collides`` of every robot ellipsoid at one
configuration. A custom **motion validator** checks a whole edge in one kernel call with
:class:`~splatplan.planners.rrt.EdgeChecker`, at the RRT's edge resolution (by default a quarter
of the robot's smallest semi-axis; no ellipsoid point moves more than that between two checked
configurations, spheres also checked between the samples), so the guarantee of the module
docstring of :mod:`splatplan.planners.rrt` holds for OMPL's paths too, simplified ones included
(the simplifier checks its shortcuts with the same validator).

**Pitfalls of the 2.0.1 wheel, guarded here.**

* ``SimpleSetup.setup()`` before start and goal are set crashes the interpreter: start and goal are
  always set first and ``setup()`` is never called here (``solve`` calls it).
* ``solve()`` holds the GIL: the termination condition is OMPL's own C++ deadline
  (``timedPlannerTerminationCondition(time_limit_s)``; a Python callable there deadlocks PRM,
  whose roadmap thread evaluates it), so the time limit holds whatever the planner. Ctrl-C: our
  SIGINT handler terminates that condition at the next validity callback on the main thread (PRM:
  at the deadline) and ``KeyboardInterrupt`` is raised after ``solve`` returns. Every callback
  into the checker takes one lock (PRM calls back from two threads).
* nanobind prints "leaked instance" warnings when the interpreter exits: after OMPL is imported,
  an exit hook points stderr at /dev/null for the interpreter's teardown only (everything printed
  by the program itself is out by then). Set ``SPLATPLAN_OMPL_LEAK_WARNINGS=1`` to see them.
* OMPL's random seed is process-global and can be set only before its first sampler exists, so
  ``seed`` is not used: OMPL's results vary from run to run (our own planners are seeded).
"""

from __future__ import annotations

import atexit
import math
import os
import signal
import sys
import threading
import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import PlanningError, SplatplanError
from .edges import EdgeChecker, check_endpoint
from .rrt import RRT
from .rrt_types import PlanResult, RRTConfig, path_length

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot

__all__ = ["available_planners", "ompl_available", "plan_ompl"]

INSTALL_HINT = "OMPL's planners need the 'ompl' extra: pip install 'splatplan[ompl]' (OMPL 2.0.x wheels, Linux/macOS)"

_hook_lock = threading.Lock()
_hook_installed = False


def _silence_stderr_at_exit() -> None:
    """Point fd 2 at /dev/null for the interpreter's teardown (nanobind's leak report)."""
    try:
        sys.stderr.flush()
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)
    except OSError:  # pragma: no cover - no fd 2
        pass


def require_ompl():
    """(ompl.base, ompl.geometric, ompl.util), quiet; or a one-line error naming the extra."""
    global _hook_installed
    try:
        import ompl.base as ob
        import ompl.geometric as og
        import ompl.util as ou
    except ImportError:
        raise SplatplanError(INSTALL_HINT) from None
    with _hook_lock:
        if not _hook_installed:
            ou.setLogLevel(ou.LOG_ERROR)  # OMPL's INFO/DEBUG lines go to stdout otherwise
            if not os.environ.get("SPLATPLAN_OMPL_LEAK_WARNINGS"):
                atexit.register(_silence_stderr_at_exit)
            _hook_installed = True
    return ob, og, ou


def ompl_available() -> bool:
    """Whether the ``ompl`` extra is installed."""
    try:
        require_ompl()
    except SplatplanError:
        return False
    return True


def available_planners() -> list[str]:
    """Names of OMPL's geometric planners in this install (e.g. RRTConnect, RRTstar, BITstar, PRM)."""
    ob, og, _ = require_ompl()
    return sorted(n for n in dir(og) if not n.startswith("_") and isinstance(getattr(og, n), type) and issubclass(getattr(og, n), ob.Planner))


def plan_ompl(
    checker: CollisionChecker,
    start,
    goal,
    *,
    robot: Robot | str,
    name: str = "RRTConnect",
    time_limit_s: float | None = 10.0,
    rrt_config: RRTConfig | None = None,
    simplify: bool = True,
    simplify_time_s: float | None = None,
    planner_range: float | None = None,
) -> PlanResult:
    """Plan from ``start`` to ``goal`` with OMPL's geometric planner ``name`` (see the module docstring).

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker` (its ``n_sigma`` sets the conservatism).
        start, goal: (D,) configurations (a point robot's centre in scene units, an arm's joints, ...).
        robot: (required) a :class:`~splatplan.robots.Robot` or a name ("panda", "sphere:0.015", ...).
        name: OMPL geometric planner class, e.g. "RRTConnect", "RRTstar", "BITstar", "PRM",
            "PRMstar", "KPIECE1" (:func:`available_planners`; an "ompl:" prefix is accepted).
        time_limit_s: wall-clock budget of ``solve`` in seconds (None: the config's, default 10 s).
            Anytime planners (RRTstar, BITstar, PRM, ...) use all of it and return their best path.
        rrt_config: box, edge resolution, frozen coordinates: the same fields our RRT reads
            (:class:`RRTConfig`; its search knobs are not used).
        simplify: shorten the path with OMPL's ``PathSimplifier`` (``SimpleSetup.simplifySolution``).
        simplify_time_s: budget of the simplifier (default: min(1 s, time_limit_s / 4)).
        planner_range: the planner's maximum motion (``setRange``, scene units of motion) where it
            has one; None = OMPL's default (a fraction of the space's extent).

    Returns:
        :class:`~splatplan.planners.rrt.PlanResult`: ``success`` = an exact solution, ``path`` (P, D)
        the simplified path, ``path_rrt`` the planner's raw path, ``n_nodes`` the vertices of the
        planner's graph (no tree arrays: ``tree_nodes`` is empty), ``info``: ``planner``,
        ``ompl_status``, ``solve_s``, ``simplify_s``, ``n_queries``, ``edge_resolution``, ``settings``.

    Raises:
        SplatplanError: the extra is missing, or ``name`` is not an OMPL geometric planner (the
            message lists them).
        PlanningError: start or goal in collision, outside the box; every coordinate frozen.
    """
    ob, og, _ = require_ompl()
    planner_name = name[5:] if name.startswith("ompl:") else name
    names = available_planners()
    if planner_name not in names:
        raise SplatplanError(f"unknown OMPL planner {planner_name!r}: available: {', '.join(names)}")
    t0 = time.perf_counter()
    cfg = rrt_config or RRTConfig()
    if time_limit_s is not None:
        cfg = replace(cfg, time_limit_s=float(time_limit_s))
    limit = cfg.time_limit_s
    if limit is None or not (limit > 0 and math.isfinite(limit)):
        raise SplatplanError(f"OMPL planners need a finite time limit > 0, got {limit}")
    rrt = RRT(checker, cfg, robot=robot)  # only for the settings and the geometry
    st = rrt.settings(start, goal)
    start = np.asarray(start, dtype=np.float64).reshape(-1)
    goal = np.asarray(goal, dtype=np.float64).reshape(-1)
    geom = rrt.geometry
    q0 = geom.n_queries
    check_endpoint(checker, geom, start, "start")
    check_endpoint(checker, geom, goal, "goal")
    free = np.nonzero(st.box_hi > st.box_lo)[0]  # coordinates OMPL plans in
    if free.size == 0:
        raise PlanningError("every coordinate is frozen (box lo == hi): nothing to plan")
    problem = _Problem(EdgeChecker(checker, geom, st.edge_resolution, inflate=rrt.inflate_edges), start, free)
    ss, si, planner, validator = _simple_setup(ob, og, problem, st, goal, planner_name, planner_range)

    t_solve = time.perf_counter()
    status = problem.run(ob, limit, ss.solve)
    solve_s = time.perf_counter() - t_solve
    if problem.stop["flag"]:
        raise KeyboardInterrupt
    exact = bool(ss.haveExactSolutionPath())
    data = ob.PlannerData(si)
    ss.getPlannerData(data)  # the planner's graph: its size is the run's node count
    n_nodes = int(data.numVertices())
    del data

    def path_now() -> np.ndarray:
        p = ss.getSolutionPath()
        return np.stack([problem.to_q(p.getState(i)) for i in range(p.getStateCount())])

    raw = path_now() if exact else None
    simplify_s = 0.0
    if exact and simplify:
        budget = min(1.0, limit / 4) if simplify_time_s is None else float(simplify_time_s)
        t1 = time.perf_counter()
        problem.run(ob, budget, ss.simplifySolution)
        simplify_s = time.perf_counter() - t1
        if problem.stop["flag"]:
            raise KeyboardInterrupt
    path = path_now() if exact else np.zeros((0, start.size))
    if exact:  # OMPL's states are float64 copies of z = q * w: pin the endpoints to the inputs exactly
        path[0], path[-1] = start, goal
    info = {
        "planner": f"ompl:{planner_name}",
        "ompl_status": str(status),
        "solve_s": solve_s,
        "simplify_s": simplify_s,
        "edge_resolution": st.edge_resolution,
        "settings": st.as_dict(),
        "n_queries": geom.n_queries - q0,
        "n_motion_checks": problem.n_motions,
        "time_limit_hit": bool(not exact and solve_s >= limit),
    }
    del ss, planner, validator  # OMPL objects before the Python validator they call
    return PlanResult(
        success=exact,
        path=path,
        length=path_length(path, geom.distance_scale()) if exact else math.inf,
        time_s=time.perf_counter() - t0,
        n_nodes=n_nodes,
        n_iters=0,
        tree_nodes=np.zeros((0, start.size)),
        tree_parents=np.zeros(0, dtype=np.int64),
        message=f"OMPL {planner_name}: {status}" + ("" if exact else f" (no exact solution within {limit:g} s)"),
        path_rrt=raw,
        info=info,
    )


class _Problem:
    """The RRT's problem as OMPL sees it: the free coordinates ``free`` (k,) of the configuration,
    each scaled by the robot's motion bound (``z = w * q``), and the checker callbacks, which
    never let an exception cross OMPL's C++ frames (the first one is re-raised after the run)."""

    def __init__(self, edges: EdgeChecker, start: np.ndarray, free: np.ndarray) -> None:
        self.edges = edges
        self.start = start  # (D,) the values of the frozen coordinates
        self.free = free
        w = edges.geometry.distance_scale()[free]
        self.w = np.where(w > 0, w, 1.0)  # (k,) configuration -> metric (a zero motion bound: plain units)
        self.k = int(free.size)
        self.errors: list[BaseException] = []
        self.stop: dict[str, Any] = {"flag": False, "ptc": None}  # ptc: the running OMPL termination condition
        self.lock = threading.Lock()  # PRM's roadmap thread calls back too; the checker is not re-entrant
        self.n_motions = 0

    def to_q(self, s) -> np.ndarray:
        """An OMPL state -> (D,) configuration."""
        q = self.start.copy()
        q[self.free] = np.fromiter((s[i] for i in range(self.k)), dtype=np.float64, count=self.k) / self.w
        return q

    def fail(self, exc: BaseException) -> None:
        """Record ``exc`` and end the search at once."""
        self.errors.append(exc)
        if self.stop["ptc"] is not None:
            self.stop["ptc"].terminate()

    def valid(self, s) -> bool:
        """OMPL's state validity checker: no robot ellipsoid in collision."""
        if self.errors:
            return False
        try:
            with self.lock:  # acquire() releases the GIL while it waits
                return not bool(self.edges.configs_collide(self.to_q(s)[None])[0])
        except BaseException as exc:  # never let an exception cross OMPL's C++ frames
            self.fail(exc)
            return False

    def motion_free(self, s1, s2) -> bool:
        """OMPL's motion validator: one batched kernel call per edge (EdgeChecker.edges_free)."""
        if self.errors:
            return False
        try:
            with self.lock:
                self.n_motions += 1
                return bool(self.edges.edges_free(self.to_q(s1)[None], self.to_q(s2)[None])[0])
        except BaseException as exc:
            self.fail(exc)
            return False

    def run(self, ob, budget: float, what):
        """``what(ptc)`` under OMPL's C++ deadline ``budget`` s (a Python termination callable
        deadlocks PRM: its roadmap thread evaluates it while solve() holds the GIL); Ctrl-C
        terminates it from our handler. Re-raises the first callback error."""
        ptc = self.stop["ptc"] = ob.timedPlannerTerminationCondition(float(budget))
        try:
            with _SigintTerminates(self.stop, ptc):
                out = what(ptc)
        finally:
            self.stop["ptc"] = None
        if self.errors:
            raise self.errors[0]
        return out


def _simple_setup(ob, og, problem: _Problem, st, goal: np.ndarray, planner_name: str, planner_range: float | None):
    """OMPL's SimpleSetup over the box of ``st`` (RRTSettings) in the scaled free coordinates, with
    ``problem``'s callbacks, start and goal set (before anything can call setup(): the 2.0.1
    crash) and the planner chosen. Returns (ss, si, planner, validator); keep them alive together."""

    class _EdgeValidator(ob.MotionValidator):
        def checkMotion(self, s1, s2) -> bool:  # noqa: N802 - OMPL's name
            return problem.motion_free(s1, s2)

    free, w, k = problem.free, problem.w, problem.k
    space = ob.RealVectorStateSpace(k)
    bounds = ob.RealVectorBounds(k)
    for i, j in enumerate(free):
        bounds.setLow(i, float(st.box_lo[j] * w[i]))
        bounds.setHigh(i, float(st.box_hi[j] * w[i]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    ss.setStateValidityChecker(problem.valid)
    si = ss.getSpaceInformation()
    validator = _EdgeValidator(si)
    si.setMotionValidator(validator)
    s_start, s_goal = si.allocState(), si.allocState()
    for i, j in enumerate(free):
        s_start[i] = float(problem.start[j] * w[i])
        s_goal[i] = float(goal[j] * w[i])
    ss.setStartAndGoalStates(s_start, s_goal)
    planner = getattr(og, planner_name)(si)
    if planner_range is not None and hasattr(planner, "setRange"):
        planner.setRange(float(planner_range))
    ss.setPlanner(planner)
    return ss, si, planner, validator


class _SigintTerminates:
    """While OMPL runs (GIL held, C++ frames on the stack): SIGINT sets ``stop["flag"]`` and
    terminates ``ptc`` instead of raising inside a callback; the caller raises KeyboardInterrupt
    afterwards (main thread only). Python runs the handler at the main thread's next callback (for
    PRM, whose main thread only waits, at the deadline)."""

    def __init__(self, stop: dict, ptc) -> None:
        self.stop = stop
        self.ptc = ptc
        self.old = None

    def _handler(self, *_):
        self.stop["flag"] = True
        self.ptc.terminate()

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.old = signal.getsignal(signal.SIGINT)
            if self.old is not signal.SIG_IGN:
                signal.signal(signal.SIGINT, self._handler)
            else:
                self.old = None
        return self

    def __exit__(self, *exc) -> None:
        if self.old is not None:
            signal.signal(signal.SIGINT, self.old)
