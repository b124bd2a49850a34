"""Shrinking-horizon MPC with a fixed goal time (:class:`GoalTimeMPC`), the schedule of the visual
reaching task (:mod:`splatplan.tasks.reach`) on one :class:`~splatplan.planners.MPPI`.

The goal cost is scored at the goal time only (e.g. a terminal image cost), which stays at the
end of the horizon T: after ``s`` executed steps the rollouts are scored at step ``T - 1 - s``.
The schedule (fields of :class:`GoalTimeSchedule`, flat in the task's config):

* **Initial plan**: ``plan_starts`` plans from zero velocity with different noise seeds,
  ``plan_start_iters`` MPPI iterations each, then ``plan_start_refine`` goal-state refinements
  (the starts' local minima are compared, not their progress); the lowest-cost one continues, up
  to ``plan_iters`` iterations in all, in chunks of ``plan_chunk`` between which the knot noise
  anneals on the goal cost's progress (``noise_cost_ref``), then ``refine_plan_iters``
  refinements (:class:`~splatplan.planners.goal_refiner.GoalRefiner`: samples that move only the
  plan's state at the goal time, with a learned covariance).
* **Tracking**: each MPC step starts with ``refine_iters`` refinements, applies the first control,
  shifts the knots (warm start; a constant velocity offset puts the plan's goal-time state back
  where it was, ``keep_goal_state``) and runs ``iters_per_step`` iterations at
  ``track_temperature``. After T steps the robot is where the plan ended.

Controls are joint velocities bounded by ``u_max`` (the refinement's offsets act on them).

**A goal search** (``search`` and ``route`` given): after the initial plan, a second one (the same
starts and iterations) runs on the ``search`` MPPI, whose costs leave out the path's collision
cost, so that a wall between the start and the goal does not bend the search towards a look-alike
goal that is easier to reach. The two plans are compared on the search costs (which goal, not which
path); when the searched one is kept and it collides under the full costs, a collision-free path to
its goal state from ``route(start, goal)`` (e.g. RRT-Connect on the same checker,
:func:`~splatplan.planners.plan`; None when there is none, e.g. the goal state itself collides:
the plan is kept and the full costs of the tracking free it) seeds it: the knots are fitted to the
path (:meth:`GoalTimeMPC.fit_path`), kept if they cost less than the plan under the full costs,
and ``route_iters`` iterations of the full costs follow. The last chunk of the initial plan and
the tracking run on the full costs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._config import ConfigTerms, bounded
from .goal_refiner import GoalRefiner
from .mppi import MPPI

__all__ = ["GoalTimeMPC", "GoalTimeSchedule"]


@dataclass
class GoalTimeSchedule(ConfigTerms):
    """The schedule of :class:`GoalTimeMPC` (fields flat in a task's config, see the module docstring)."""

    #: knot noise at the last MPC step as a fraction of noise_sigma (linear in the remaining
    #: horizon: finer exploration as the goal time approaches); 1 = constant noise
    noise_final: float = bounded(0.3, ge=0)
    #: noise annealing on the goal (image) cost's progress: the knot noise is further scaled by
    #: clip(sqrt(c / noise_cost_ref), noise_min_scale, 1), c = raw goal cost of the current plan
    #: (the pose error grows like sqrt(c) near the goal); 0 = off
    noise_cost_ref: float = bounded(4.0, ge=0)
    #: lower bound of that scale
    noise_min_scale: float = bounded(0.03, ge=0, le=1)
    #: with annealing, the initial plan runs in chunks of this many iterations (annealed in between)
    plan_chunk: int = bounded(5, ge=1)
    #: MPPI temperature while the robot moves (after the initial plan; None = temperature): a small one
    #: keeps the plan's nominal (always among the samples) unless a sample beats it, so the warm-started
    #: plan does not drift through the weighted averaging of one iteration per step
    track_temperature: float | None = bounded(0.02, gt=0)
    #: after each warm-start shift, offset the knots so that the plan's state at the goal time stays
    #: where the plan had it (the least-squares shift alone drifts it over the run)
    keep_goal_state: bool = True
    #: MPPI iterations before the first control is applied
    plan_iters: int = bounded(60, ge=1)
    #: multi-start initial plan: this many plans (noise seeds seed, seed + 1, ...) each run
    #: plan_start_iters iterations from zero velocity; the lowest-cost one continues (1 = one start)
    plan_starts: int = bounded(3, ge=1)
    #: MPPI iterations of each start of a multi-start initial plan (counted within plan_iters)
    plan_start_iters: int = bounded(30, ge=1)
    #: goal-state refinement iterations ending each start of a multi-start plan, before the starts
    #: are compared (a look-alike view and the goal's basin then differ in cost; 0 = compare as is)
    plan_start_refine: int = bounded(10, ge=0)
    #: MPPI iterations per later MPC step
    iters_per_step: int = bounded(2, ge=1)
    #: the last final_steps MPC steps run final_iters iterations each (fine convergence at the goal)
    final_steps: int = bounded(0, ge=0)
    #: MPPI iterations per step over the last final_steps steps
    final_iters: int = bounded(3, ge=1)
    #: goal-state refinement (GoalRefiner): iterations per MPC step whose K samples move
    #: only the plan's state at the goal time, by joint offsets (a constant velocity offset on every
    #: knot); the cheapest sample (the plan itself among them) is kept
    refine_iters: int = bounded(1, ge=0)
    #: refinement iterations after the initial plan (before the first control)
    refine_plan_iters: int = bounded(20, ge=0)
    #: initial std of those joint offsets (rad); it grows x refine_grow after an improving
    #: iteration and shrinks x refine_shrink otherwise, within [refine_sigma_min, refine_sigma]
    refine_sigma: float = bounded(0.05, ge=0)
    #: lower bound of the refinement std (rad)
    refine_sigma_min: float = bounded(0.002, ge=0)
    #: with a goal search and a route (GoalTimeMPC's search / route): MPPI iterations of the full costs
    #: after a routed plan is fitted
    route_iters: int = bounded(10, ge=0)
    #: growth of the refinement std after an improvement
    refine_grow: float = bounded(1.5, ge=1)
    #: shrink of the refinement std after an iteration without improvement
    refine_shrink: float = bounded(0.6, gt=0, le=1)


class GoalTimeMPC:
    """The schedule of the module docstring on ``mppi`` (its config has ``report_nominal`` on: the
    nominal's ``progress_value``, a raw goal cost the goal cost term reports, anneals the noise;
    ``u_max`` (du,): the control bound, also of the refinement). Counts the MPPI iterations in
    ``iters``; ``start_costs`` are the multi-start costs."""

    def __init__(
        self, mppi: MPPI, schedule: GoalTimeSchedule, u_max: np.ndarray, progress_value: str, *,
        search: MPPI | None = None, route: Callable[[np.ndarray, np.ndarray], np.ndarray | None] | None = None,
    ) -> None:  # fmt: skip
        self.cfg, self.mppi, self.mcfg = schedule, mppi, mppi.config
        self.dyn, self.vmax, self.value = mppi.dynamics, np.asarray(u_max, np.float64), progress_value
        self.search, self.route = search, route
        self.refiner = self._new_refiner()
        self.iters = 0
        #: the multi-start costs
        self.start_costs: list[float] = []
        #: with a goal search: the search costs of the plain and the searched initial plans
        self.search_costs: tuple[float, float] | None = None
        #: what the route step did: "not asked" / "searched plan free" / "no route found" / "route costs more" / "routed"
        self.route_outcome = "not asked"

    @property
    def kept_search(self) -> bool:
        """Whether the goal search's plan was kept (its search cost below the plain plan's)."""
        return self.search_costs is not None and self.search_costs[1] < self.search_costs[0]

    def anneal(self, c: float) -> float:
        """Noise scale from the raw goal cost ``c`` of the current plan."""
        cfg = self.cfg
        return float(np.clip(np.sqrt(c / cfg.noise_cost_ref), cfg.noise_min_scale, 1.0)) if cfg.noise_cost_ref > 0 else 1.0

    def plan_chunk(self, q: np.ndarray, n: int, scale: float):
        """n MPPI iterations at noise scale ``scale``, nothing executed (the warm-start shift is
        undone); returns the step's info and the noise scale annealed on the plan's goal cost."""
        self.mppi.set_noise_scale(scale)
        _, info = self.mppi.step(q, n_iters=n)
        self.mppi.reset(info.nominal_knots)
        return info, self.anneal(float(np.min(info.nominal_values[self.value])))

    def _new_refiner(self, *key: int) -> GoalRefiner:
        cfg = self.cfg
        rng = np.random.default_rng([self.mcfg.seed, 1, *key])
        return GoalRefiner(self.mppi.du, self.mcfg.n_samples, cfg.refine_sigma, sigma_min=cfg.refine_sigma_min, grow=cfg.refine_grow, shrink=cfg.refine_shrink, rng=rng)

    def refine(self, q: np.ndarray, n: int, m: int, goal_step: int | None = None) -> float:
        """n refinement iterations of the plan's state at the goal time (m controls ahead): offset d_k
        moves it through the knot offset d_k / (m dt) (the B-spline basis sums to 1). Returns the
        total cost of the kept plan (inf when n = 0)."""
        kept = np.inf
        for _ in range(n):
            d = self.refiner.sample()  # (K, du), row 0 = 0 (the plan itself)
            samples = np.clip(self.mppi.knots[None] + d[:, None, :] / (m * self.mcfg.dt), -self.vmax, self.vmax)  # (K, n_knots, du)
            total = self.mppi.evaluate(q, samples, goal_step).total
            b = self.refiner.update(d, total)
            self.mppi.reset(samples[b])
            kept = float(total[b])
        return kept

    def initial_plan(self, q: np.ndarray, chunk: int) -> tuple[int, float]:
        """The multi-start plan (when ``plan_starts`` > 1) and the rest of ``plan_iters`` but the last
        chunk, on the current MPPI; returns the iterations done on the kept plan and its noise scale."""
        cfg, mppi = self.cfg, self.mppi
        done, scale = 0, 1.0
        if cfg.plan_starts > 1:  # several short plans from zero velocity, each with its own noise; the best continues
            n0 = min(cfg.plan_start_iters, cfg.plan_iters - 1)
            starts = []
            for j in range(cfg.plan_starts):
                mppi.reset(rng=self.mcfg.seed + j)
                sc, left = 1.0, n0
                while left > 0:
                    n = min(chunk, left)
                    info, sc = self.plan_chunk(q, n, sc)
                    left -= n
                cost, knots = info.nominal_cost, info.nominal_knots
                if cfg.plan_start_refine > 0:  # compare the starts' local minima, not their progress
                    self.refiner = self._new_refiner(j)
                    cost, knots = self.refine(q, cfg.plan_start_refine, self.mcfg.horizon), mppi.knots.copy()
                starts.append((cost, j, knots, sc, mppi.rng, self.refiner))
            self.start_costs = [round(float(e[0]), 4) for e in starts]
            _, _, knots, scale, rng, self.refiner = min(starts, key=lambda e: (e[0], e[1]))
            mppi.reset(knots, rng=rng)
            done = n0  # the chosen start's iterations; the other starts' are extra
            self.iters += n0 * (cfg.plan_starts - 1) + cfg.plan_start_refine * cfg.plan_starts
        while cfg.plan_iters - done > chunk:
            _, scale = self.plan_chunk(q, chunk, scale)
            done += chunk
        self.iters += done
        if cfg.refine_plan_iters > 0:
            self.refine(q, cfg.refine_plan_iters, self.mcfg.horizon)
            self.iters += cfg.refine_plan_iters
        return done, scale

    def goal_search(self, q: np.ndarray, chunk: int, done: int, scale: float) -> tuple[int, float]:
        """The goal search (module docstring) after the plain initial plan (``done`` iterations, noise
        scale ``scale``); returns the kept plan's iterations and noise scale."""
        search = self.search
        assert search is not None
        full, plain = self.mppi, (self.mppi.knots.copy(), self.mppi.rng, self.refiner, self.start_costs, done, scale)
        self.mppi = search
        try:
            done_s, scale_s = self.initial_plan(q, chunk)
        finally:
            self.mppi = full
        c_plain, c_search = search.evaluate(q, np.stack([plain[0], search.knots])).total
        self.search_costs = (float(c_plain), float(c_search))
        if not self.kept_search:
            knots, rng, self.refiner, self.start_costs, done, scale = plain
            full.reset(knots, rng=rng)
            return done, scale
        full.reset(search.knots, rng=search.rng)
        return done_s, self.route_plan(q, scale_s)

    def fit_path(self, q: np.ndarray, path: np.ndarray, goal_step: int) -> np.ndarray:
        """Knots (n_knots, du) whose rollout from ``q`` follows ``path`` (N, dx) (path[0] = q) and reaches
        its end at ``goal_step``, holding it after: the path timed at a constant fraction of the velocity
        bound (segment time max_j |dq_j| / u_max_j), the knots by least squares on the rollout, which is
        linear in them (the joint integrator within its limits); the goal state weighs 10x, clipped."""
        mppi, t_len = self.mppi, self.mcfg.horizon
        path = np.asarray(path, np.float64)
        vmax = self.vmax[: path.shape[1]]
        step = np.abs(np.diff(path, axis=0))  # (N - 1, dx); a dimension without speed (bound 0) sets no time
        seg = np.max(np.divide(step, vmax, out=np.zeros_like(step), where=vmax > 0), axis=1)  # (N - 1,) segment times at full speed
        t = np.concatenate([[0.0], np.cumsum(seg)])
        if not t[-1] > 0:
            t = np.linspace(0.0, 1.0, len(path))
        frac = np.minimum(np.arange(1, t_len + 1) / (goal_step + 1), 1.0) * t[-1]  # (T,) path time at each rollout step
        target = np.stack([np.interp(frac, t, path[:, j]) for j in range(path.shape[1])], axis=1)  # (T, dx)
        n, du = mppi.knots.shape
        basis = np.concatenate([np.zeros((1, n * du)), np.eye(n * du)]).reshape(-1, n, du)  # (1 + n du, n, du)
        roll = self.dyn.rollout(q, mppi.spline(basis), self.mcfg.dt)  # (1 + n du, T, dx)
        a = (roll[1:] - roll[0]).reshape(n * du, -1).T  # (T dx, n du): states = roll[0] + a @ knots
        w_step = np.ones((t_len, 1))
        w_step[goal_step] = 10.0
        w = np.broadcast_to(w_step, target.shape).reshape(-1)  # (T dx,)
        sol, *_ = np.linalg.lstsq(a * w[:, None], (target - roll[0]).reshape(-1) * w, rcond=None)
        return mppi.clip(sol.reshape(n, du))

    def route_plan(self, q: np.ndarray, scale: float) -> float:
        """The route step of a goal search (module docstring) on the kept plan; returns the noise scale.
        Outcomes (:attr:`route_outcome`): "searched plan free", "no route found" (e.g. the goal state
        collides: the plan is kept, the full costs of the rest of the schedule free it), "route costs
        more", "routed"."""
        mppi, goal = self.mppi, self.mcfg.horizon - 1
        ev = mppi.evaluate(q, mppi.knots[None], goal)
        if not ev.in_collision()[0]:
            self.route_outcome = "searched plan free"
            return scale
        path = self.route(q, ev.states[0, goal]) if self.route is not None else None
        if path is None:  # the goal state collides (or no path in time): the tracking's full costs move it
            self.route_outcome = "no route found"
            return scale
        knots = self.fit_path(q, path, goal)
        if not mppi.evaluate(q, knots[None], goal).total[0] < ev.total[0]:
            self.route_outcome = "route costs more"
            return scale
        self.route_outcome = "routed"
        mppi.reset(knots)
        if self.cfg.route_iters > 0:
            _, scale = self.plan_chunk(q, self.cfg.route_iters, scale)
            self.iters += self.cfg.route_iters
        return scale

    def execute(self, q: np.ndarray, on_step=None) -> tuple[list, list]:
        """Plan, then execute the T steps; returns the states (T + 1, dx) and the per-step raw goal
        cost of the plan. ``on_step(s, state, value)`` after each executed step."""
        cfg, mppi, t_len = self.cfg, self.mppi, self.mcfg.horizon
        states, trace = [q.copy()], []
        chunk = max(1, cfg.plan_chunk) if cfg.noise_cost_ref > 0 else cfg.plan_iters  # the noise anneals on progress between chunks
        done, scale = self.initial_plan(q, chunk)
        if self.search is not None:
            done, scale = self.goal_search(q, chunk, done, scale)
        for s in range(t_len):
            goal = t_len - 1 - s  # the goal time stays at T; the rollout's tail beyond it is never executed
            if s > 0 and cfg.refine_iters > 0:
                self.refine(q, cfg.refine_iters, t_len - s, goal)
                self.iters += cfg.refine_iters
            n_iters = cfg.plan_iters - done if s == 0 else (cfg.final_iters if s >= t_len - cfg.final_steps else cfg.iters_per_step)
            lam = self.mcfg.temperature if s == 0 or cfg.track_temperature is None else cfg.track_temperature
            mppi.set_noise_scale(scale, cfg.noise_final + (1.0 - cfg.noise_final) * (t_len - s) / t_len)
            u, info = mppi.step(q, n_iters=n_iters, temperature=lam, goal_step=goal)
            self.iters += n_iters
            q = self.dyn.rollout(q, u[None, None, :], self.mcfg.dt)[0, 0]
            states.append(q.copy())
            if cfg.keep_goal_state and s + 1 < t_len:
                # the least-squares warm-start shift moves the plan's state at the goal time; a constant
                # velocity offset (the B-spline basis sums to 1) puts it back where the plan had it
                m = t_len - 1 - s  # controls from the new state up to the goal time
                shifted = self.dyn.rollout(q, mppi.spline(mppi.knots[None]), self.mcfg.dt)[0, m - 1]
                mppi.reset(mppi.knots + (info.nominal_states[goal] - shifted)[: mppi.du] / (m * self.mcfg.dt))
            best = float(np.min(info.nominal_values[self.value]))  # raw goal cost of the updated nominal plan
            trace.append(best)
            scale = self.anneal(best)
            if on_step is not None:
                on_step(s, q, best)
        return states, trace
