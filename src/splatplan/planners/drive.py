"""Goal-only driving of a planar base under :class:`~splatplan.planners.MPPI`: a goal-cost field
(:class:`DriveGoalCost`) and a sampling strategy (:class:`StructuredDrives`) that together get a
base to a goal position around obstacles and through doorways, from the goal and the collision
checks near the base only (no prior map, no route). Used by :mod:`splatplan.tasks.base` (the Go2).

State (x, y, yaw) of the base in the world (metres, radians); controls (vx, vy, wz) in the body
frame (:class:`~splatplan.planners.dynamics.PlanarBase`), knots of a B-spline over the horizon.

* **Goal cost** (:class:`DriveGoalCost`): ``w_goal (sum_t d_t + terminal_factor d_T + min_factor
  min_t d_t)`` with d the distance of the base to the goal, plus ``w_heading`` for facing the goal
  (without it the heading drifts, and a long body meets a doorway sideways). With a field
  (:class:`~splatplan.planners.memory.ObstacleMemory`) d is the **geodesic** distance to the goal
  on the cells sensed so far, and the heading term faces the field's descent. During a sweep of
  the recovery (below) the term is the sweep's instead: progress along its direction (``w_sweep``)
  and facing it (``w_align``). It reports the straight-line distances ("goal_distance", (K, T))
  and the goal term ("goal_cost", (K,)) as values in every mode.
* **Structured samples** (:class:`StructuredDrives`): next to the Gaussian knot perturbations of
  the nominal, straight drives in ``n_directions`` world directions and the same drives switching
  to the bearing to the goal after 1/4, 1/2 and 3/4 of the horizon (knots fitted by ridge least
  squares), all turning the base towards their direction of travel (``turn_rate``). They let MPPI
  see "along the wall, then through the doorway". With a field, the drives switch to following its
  descent (streamlines) instead, plus two pure followers. The drive along the bearing and the
  switching drives **stop at the goal** (:meth:`StructuredDrives._to_target`): in a small room a
  drive that ran on at full speed met the far wall within the horizon and lost to standing still.
* **Route tracking** (:class:`RouteTracker`): a driver that follows a route (e.g. from the RRT)
  sets the goal term's ``goal`` to the route's point ``lookahead`` ahead of the base's progress
  and ``heading_ref`` to the route's heading there; the heading term then faces ``heading_ref``
  (no cutoff near the goal) and the drives turn towards it instead of their direction of travel
  (in a narrow passage only the few headings the RRT found free fit).
* **Stagnation recovery** (``recovery``): when the distance to the goal has not improved by
  ``stuck_progress_m`` for ``stuck_steps`` steps (and the base is more than ``min_distance_m``
  from the goal), the base sidesteps: it sweeps perpendicular to the bearing to the goal, first to
  the side ``first_sweep`` (clockwise by default, a fixed convention like the Bug algorithms'
  turning direction; the other side where an earlier sweep started within 0.5 m), facing its
  direction of travel, and reverses with twice the length when blocked or after ``detour_length_m``
  (a doubling search). It ends as soon as a collision-free rollout gets ``exit_margin_m`` closer to
  the goal than the base ever was and than any collision-free rollout of goal mode ever got; the
  nominal then becomes that rollout (:meth:`StructuredDrives.select`). Every sweep, reversal and
  resume is recorded in ``events``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._config import ConfigTerms, bounded
from ..errors import SplatplanError
from .cost_base import Cost, CostValue, Rollout
from .mppi import MPPI, Evaluation, SamplingStrategy

__all__ = ["DriveGoalCost", "DriveTerms", "RouteTracker", "StructuredDrives"]


class DriveGoalCost(Cost):
    """Goal term of a planar base (see the module docstring): one term, "goal" (or "sweep" during a
    recovery sweep), and the values "goal_distance" (K, T) (straight line, m) and "goal_cost" (K,).

    Attributes a driver may set between steps: ``goal`` (2,) (e.g. the next waypoint of a route),
    ``heading_ref`` (rad; route tracking: the heading term faces it, ``w_heading sum_t (1 -
    cos(yaw_t - heading_ref))`` all the way, instead of the bearing to the goal; None = the
    bearing), ``sweep`` = (heading rad, origin (2,)) during a recovery sweep, None otherwise.
    """

    name = "goal"

    def __init__(self, goal, *, w_goal: float = 1.0, terminal_factor: float = 5.0, min_factor: float = 5.0, w_heading: float = 0.5,
                 w_sweep: float = 0.3, w_align: float = 1.0, field=None) -> None:  # fmt: skip
        self.goal = np.asarray(goal, np.float64).reshape(2)
        self.w_goal, self.terminal_factor, self.min_factor, self.w_heading = float(w_goal), float(terminal_factor), float(min_factor), float(w_heading)
        self.w_sweep, self.w_align = float(w_sweep), float(w_align)
        #: a geodesic goal-distance field (``distance(xy)``, ``heading(xy)``; an ObstacleMemory), or None = straight line
        self.field = field
        self.sweep: tuple[float, np.ndarray] | None = None
        self.heading_ref: float | None = None  # route tracking: the yaw to face (rad), instead of the bearing to the goal

    def goal_cost(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(K,) goal-mode cost and (K, T) straight-line distances of states (K, T, 3)."""
        dist = np.linalg.norm(states[..., :2] - self.goal, axis=-1)  # (K, T) m, straight line
        gd = dist if self.field is None else self.field.distance(states[..., :2])  # (K, T) m, geodesic on the field
        goal = self.w_goal * (gd.sum(axis=1) + self.terminal_factor * gd[:, -1] + self.min_factor * gd.min(axis=1))
        if self.w_heading > 0 and self.heading_ref is not None:  # route tracking: the route's heading, all the way
            goal = goal + self.w_heading * (1.0 - np.cos(states[..., 2] - self.heading_ref)).sum(axis=1)
        elif self.w_heading > 0:
            if self.field is None:
                bearing = np.arctan2(self.goal[1] - states[..., 1], self.goal[0] - states[..., 0])
            else:  # face along the geodesic
                bearing = self.field.heading(states[..., :2])
            goal = goal + self.w_heading * np.where(dist < 0.3, 0.0, 1.0 - np.cos(states[..., 2] - bearing)).sum(axis=1)
        return goal, dist

    def evaluate(self, rollout: Rollout) -> CostValue:
        goal, dist = self.goal_cost(rollout.states)
        values = {"goal_distance": dist, "goal_cost": goal}
        if self.sweep is None:
            return CostValue({"goal": goal}, values)
        heading, origin = self.sweep
        d = np.array([np.cos(heading), np.sin(heading)])
        prog = (rollout.states[..., :2] - origin) @ d  # (K, T) m along the swept heading
        align = (1.0 - np.cos(rollout.states[..., 2] - heading)).sum(axis=1)  # walk forward
        return CostValue({"sweep": -self.w_sweep * prog.sum(axis=1) + self.w_align * align}, values)

    def __call__(self, rollout: Rollout) -> np.ndarray:
        return np.sum(list(self.evaluate(rollout).terms.values()), axis=0)


class StructuredDrives(SamplingStrategy):
    """Sampling of :class:`MPPI` for goal-only driving (see the module docstring): structured drives
    plus ``n_samples - P`` (at least 1) Gaussian knot perturbations of the nominal (the first
    unperturbed), and the stagnation recovery. Needs the :class:`DriveGoalCost` among MPPI's costs
    (the recovery switches it between goal and sweep mode) and ``n_iters = 1``.

    Args:
        goal_cost: the :class:`DriveGoalCost` (its ``goal`` and ``field`` steer the drives).
        n_directions: world directions of the straight drives (0 = no structured samples).
        speed: speed of the drives (m/s); turn_rate: their turn rate towards the direction of travel (rad/s).
        recovery: enable the stagnation recovery; the other arguments are its settings (module docstring).
    """

    def __init__(self, goal_cost: DriveGoalCost, *, n_directions: int = 8, speed: float = 0.8, turn_rate: float = 1.5,
                 recovery: bool = False, stuck_steps: int = 10, min_distance_m: float = 0.5, stuck_progress_m: float = 0.05,
                 detour_length_m: float = 2.0, exit_margin_m: float = 0.3, first_sweep: int = -1) -> None:  # fmt: skip
        self.goal_cost = goal_cost
        self.n_directions, self.speed, self.turn_rate = int(n_directions), float(speed), float(turn_rate)
        self.recovery, self.stuck_steps, self.min_distance_m, self.stuck_progress_m = bool(recovery), int(stuck_steps), float(min_distance_m), float(stuck_progress_m)
        self.detour_length_m, self.exit_margin_m, self.first_sweep = float(detour_length_m), float(exit_margin_m), int(first_sweep)
        self._basis_pinv: np.ndarray | None = None  # (n_knots, T) controls -> knots, from the MPPI's spline (bind)
        self.mode = "goal"
        self.best = np.inf  # best distance to the goal reached so far (m)
        self.best_step = 0
        self.step_i = -1
        self.detour: dict | None = None
        self.events: list[dict] = []
        self.seen = np.inf  # closest approach to the goal of the goal-mode steps' collision-free rollouts (m)

    def bind(self, basis: np.ndarray, dt: float) -> None:
        """Use the spline basis (T, n_knots) and control period ``dt`` (s) of the MPPI (done by the
        first :meth:`begin_step`)."""
        bb = np.asarray(basis, np.float64)  # ridge: the unclamped first / last knots barely act, unregularised they blow up
        self.horizon, self.n_knots = bb.shape
        self.dt = float(dt)
        self._basis_pinv = np.linalg.solve(bb.T @ bb + 0.1 * np.eye(self.n_knots), bb.T)

    # ---------------------------------------------------------------- samples
    def _drive_knots(self, x: np.ndarray, v_world: np.ndarray) -> np.ndarray:
        """(P, T, 2) world-frame velocities per control step -> (P, n_knots, 3) body-frame knots
        (least-squares fit of the controls) that also turn the base towards its direction of
        travel (the goal term's ``heading_ref`` when set: a tracked route's heading) at up to
        ``turn_rate``; a stopped drive (zero velocity) keeps its heading."""
        p, t_len, _ = v_world.shape
        u = np.zeros((p, t_len, 3))
        yaw = np.full(p, float(x[2]))
        ref = self.goal_cost.heading_ref
        for t in range(t_len):
            psi = np.arctan2(v_world[:, t, 1], v_world[:, t, 0]) if ref is None else np.full(p, float(ref))
            wz = np.clip(np.angle(np.exp(1j * (psi - yaw))) / self.dt, -self.turn_rate, self.turn_rate)
            wz = np.where(np.hypot(v_world[:, t, 0], v_world[:, t, 1]) > 1e-9, wz, 0.0)  # stopped: keep the heading
            c, s_ = np.cos(yaw), np.sin(yaw)
            u[:, t, 0] = c * v_world[:, t, 0] + s_ * v_world[:, t, 1]
            u[:, t, 1] = -s_ * v_world[:, t, 0] + c * v_world[:, t, 1]
            u[:, t, 2] = wz
            yaw = yaw + wz * self.dt
        assert self._basis_pinv is not None  # (bound by the first begin_step)
        return np.einsum("nt,ptd->pnd", self._basis_pinv, u)

    def primitives(self, x: np.ndarray) -> np.ndarray:
        """(P, n_knots, 3) structured samples: straight drives in ``n_directions`` world
        directions (one is the bearing to the target: the goal, or the sweep's direction), and
        the same drives switching to the target (from the predicted switch point) after 1/4, 1/2
        and 3/4 of the horizon; the drive along the bearing and the switching ones stop at the
        target (:meth:`_to_target`). All turn the base towards their direction of travel. With a
        field (memory mode) the drives follow its descent instead (:meth:`_followers`)."""
        m, t_len = self.n_directions, self.horizon
        if m <= 0:
            return np.zeros((0, self.n_knots, 3))
        tgt = self.goal_cost.goal
        if self.mode == "detour" and self.detour is not None:  # (a detour mode has its detour)
            tgt = x[:2] + 10.0 * np.array([np.cos(self.detour["heading"]), np.sin(self.detour["heading"])])
        field = self.goal_cost.field
        geo = field is not None and self.mode == "goal"  # the target's direction: descent of the field
        b = float(field.heading(x[:2])) if geo else float(np.arctan2(tgt[1] - x[1], tgt[0] - x[0]))
        th = b + 2 * np.pi * np.arange(m) / m  # (m,)
        v = self.speed * np.stack([np.cos(th), np.sin(th)], axis=1)  # (m, 2) world, m/s
        vw = [np.repeat(v[:, None], t_len, axis=1)]  # straight
        if geo:  # the same drives following the field's descent from their switch points, and two pure followers
            return self._drive_knots(x, np.concatenate(vw + self._followers(x, v, t_len)))
        vw[0][0] = self._to_target(x[:2], tgt, 0, vw[0][:1])[0]  # the drive along the bearing stops at the target
        for frac in (0.25, 0.5, 0.75):
            j = max(1, int(round(frac * t_len)))
            vw.append(self._to_target(x[:2], tgt, j, np.repeat(v[:, None], t_len, axis=1)))
        return self._drive_knots(x, np.concatenate(vw))

    def _to_target(self, xy: np.ndarray, tgt: np.ndarray, j: int, vel: np.ndarray) -> np.ndarray:
        """(P, T, 2) world velocities ``vel`` whose steps from ``j`` on are replaced by a drive to
        ``tgt`` (2,) that **stops at it**: a drive that overshot the goal would run into the far wall
        of a small room within the horizon and lose to standing still. The speed is ``speed``, or
        less where the target is nearer than that covers in half the remaining horizon
        (``min(speed, distance / (half the remaining horizon))``: a short drive stretched over
        several steps, since the knots' B-spline cannot hold a one-step pulse)."""
        out = np.array(vel, np.float64, copy=True)  # (P, T, 2) world, m/s
        p = xy + out[:, :j].sum(axis=1) * self.dt  # (P, 2) world, the switch points
        half = max(1, (out.shape[1] - j) // 2) * self.dt  # s
        speed = np.minimum(self.speed, np.linalg.norm(tgt - p, axis=1, keepdims=True) / half)  # (P, 1) m/s
        for t in range(j, out.shape[1]):
            d = tgt - p  # (P, 2)
            n = np.linalg.norm(d, axis=1, keepdims=True)
            out[:, t] = d / np.maximum(n, 1e-9) * np.minimum(speed, n / self.dt)  # the last step lands on the target
            p = p + out[:, t] * self.dt
        return out

    def _followers(self, x: np.ndarray, v: np.ndarray, t_len: int) -> list[np.ndarray]:
        """Field mode: (m, T, 2) world velocities of the drives ``v`` (m, 2) switching after 1/4,
        1/2, 3/4 of the horizon to following the descent of the field (a streamline integrated
        from the predicted switch point), and (2, T, 2) pure followers at full and half speed."""
        field = self.goal_cost.field
        out = []
        for frac in (0.25, 0.5, 0.75, 0.0):
            j = int(round(frac * t_len))
            vel = np.repeat(v[:, None], t_len, axis=1) if j else np.zeros((2, t_len, 2))  # (P, T, 2) world, m/s
            speed = np.full((len(vel), 1), self.speed) if j else self.speed * np.array([[1.0], [0.5]])  # (P, 1) m/s
            p = x[:2] + vel[:, 0] * j * self.dt  # (P, 2) world, the switch points
            for t in range(j, t_len):
                h = field.heading(p)
                vel[:, t] = speed * np.stack([np.cos(h), np.sin(h)], axis=1)
                p = p + vel[:, t] * self.dt
            out.append(vel)
        return out

    def sample(self, mppi: MPPI, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The structured drives, then the nominal and its Gaussian perturbations (K = n_samples - P, at least 1)."""
        prim = self.primitives(x)
        k_rand = max(mppi.config.n_samples - len(prim), 1)
        eps = rng.standard_normal((k_rand, mppi.config.n_knots, mppi.du)) * mppi.sigma
        eps[0] = 0.0  # the nominal itself
        return np.concatenate([prim, mppi.knots[None] + eps])

    # ---------------------------------------------------------------- recovery
    def begin_step(self, mppi: MPPI, x: np.ndarray) -> None:
        """The stagnation bookkeeping of a new MPC step: may start or reverse a sweep."""
        if self._basis_pinv is None:
            self.bind(mppi.spline.basis, mppi.config.dt)
        self.step_i += 1
        dist_now = float(np.linalg.norm(x[:2] - self.goal_cost.goal))
        if dist_now < self.best - self.stuck_progress_m:
            self.best, self.best_step = dist_now, self.step_i
        if self.recovery and self.mode == "goal" and self.step_i - self.best_step >= self.stuck_steps and dist_now > self.min_distance_m:
            self._start_detour(x)
        if self.mode == "detour" and self.detour is not None:
            det = self.detour
            det["walked"] += float(np.linalg.norm(x[:2] - det["last"]))
            det["last"] = x[:2].copy()
            det["window"] = (det["window"] + [x[:2].copy()])[-self.stuck_steps :]
            blocked = len(det["window"]) == self.stuck_steps and np.linalg.norm(det["window"][-1] - det["window"][0]) < 2 * self.stuck_progress_m
            if blocked or det["walked"] >= det["limit"]:  # sweep back the other way, twice as far
                det["heading"] += np.pi
                det["side"] = -det["side"]
                det["limit"] = 2.0 * det["limit"] + det["walked"]
                det["walked"], det["window"] = 0.0, [x[:2].copy()]
                self.events.append({"step": self.step_i, "event": "reverse", "xy": x[:2].round(3).tolist()})
        self.goal_cost.sweep = (self.detour["heading"], x[:2].copy()) if self.mode == "detour" and self.detour is not None else None

    def _start_detour(self, x: np.ndarray) -> None:
        """Stagnation: sidestep, perpendicular to the bearing to the goal, first to the side
        ``first_sweep`` (the other side where an earlier sweep started within 0.5 m: that one did
        not lead out), reversing with doubled length when blocked or done."""
        g = self.goal_cost.goal
        bearing = float(np.arctan2(g[1] - x[1], g[0] - x[0]))
        side = float(np.sign(self.first_sweep) or 1.0)
        for e in self.events:
            if e["event"] == "detour" and np.linalg.norm(np.asarray(e["xy"]) - x[:2]) < 0.5:
                side = -e["side_sign"]
        self.detour = {"ref": min(self.best, self.seen), "side": side, "heading": bearing + side * np.pi / 2, "limit": self.detour_length_m, "walked": 0.0, "last": x[:2].copy(), "window": [x[:2].copy()]}
        self.mode = "detour"
        self.events.append({"step": self.step_i, "event": "detour", "xy": x[:2].round(3).tolist(), "side": "counterclockwise" if side > 0 else "clockwise", "side_sign": side, "distance_m": round(float(self.best), 3)})

    def select(self, mppi: MPPI, x: np.ndarray, samples: np.ndarray, evaluation: Evaluation) -> np.ndarray | None:
        """Leave a sweep when a collision-free rollout gets clearly closer to the goal than ever
        before (its knots become the nominal); in goal mode remember the closest approach of the
        collision-free rollouts."""
        dmin = evaluation.values["goal_distance"].min(axis=1)  # (K,)
        free = ~evaluation.in_collision()
        chosen = None
        if self.mode == "detour" and self.detour is not None:
            ok = free & (dmin < self.detour["ref"] - self.exit_margin_m)
            if ok.any():
                base = 0.0
                for name, v in evaluation.terms.items():
                    base = base if name == "sweep" else base + v
                i = int(np.flatnonzero(ok)[np.argmin((base + evaluation.values["goal_cost"])[ok])])
                self.events.append({"step": self.step_i, "event": "resume", "xy": x[:2].round(3).tolist(), "rollout_distance_m": round(float(evaluation.values["goal_distance"][i].min()), 3)})
                self.mode, self.detour, self.goal_cost.sweep = "goal", None, None
                self.best_step = self.step_i
                chosen = samples[i].copy()
        if self.mode == "goal":  # what goal mode can see: the closest approach of a collision-free rollout
            self.seen = min(self.seen, float(dmin[free].min()) if free.any() else np.inf)
        return chosen


class RouteTracker:
    """Where a base heads along a route: the point ``lookahead`` (m of arc length) ahead of its
    progress, and the route's yaw there (the heading term faces it: :attr:`DriveGoalCost.heading_ref`).
    Progress is the nearest point of the route (resampled every ``step`` m) within ``2 lookahead``
    past the last progress (so it advances at most ``2 lookahead`` per call) and never goes back,
    so a route that doubles back on itself is followed in order.

    Args:
        route: (P, 2) or (P, 3) waypoints x, y[, yaw] (world, m, rad); without yaws each segment
            faces along itself.
        lookahead: arc length (m) of the target ahead of the progress.
        step: resampling step (m).
    """

    def __init__(self, route: np.ndarray, lookahead: float, step: float = 0.02) -> None:
        r = np.asarray(route, np.float64)  # (P, 2) or (P, 3) x, y[, yaw]
        if r.ndim != 2 or r.shape[1] < 2 or len(r) < 1:
            raise SplatplanError(f"a route must be (P, 2) or (P, 3) waypoints, got shape {r.shape}")
        yawed = r.shape[1] >= 3  # else each segment faces along itself
        r = np.c_[r[:, :2], np.unwrap(r[:, 2]) if yawed else np.zeros(len(r))]
        pts = [r[:1]]
        for a, b in zip(r[:-1], r[1:]):
            if not yawed:
                a, b = a.copy(), b.copy()
                a[2] = b[2] = np.arctan2(b[1] - a[1], b[0] - a[0])
            n = max(1, int(np.ceil(np.linalg.norm(b[:2] - a[:2]) / step)))
            pts.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
        if not yawed and len(pts) > 1:
            pts[0] = pts[0].copy()
            pts[0][0, 2] = pts[1][0, 2]
        self.dense = np.concatenate(pts)  # (M, 3) x, y, yaw (unwrapped)
        self.arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.dense[:, :2], axis=0), axis=1))]  # (M,) m
        self.lookahead = float(lookahead)
        self.s = 0.0  # progress (m of arc length)

    def target(self, xy: np.ndarray) -> tuple[np.ndarray, float]:
        """(target xy (2,), route yaw there (rad)) for the base at ``xy`` (2,); advances the progress."""
        win = np.flatnonzero((self.arc >= self.s) & (self.arc <= self.s + 2.0 * self.lookahead))
        i = int(win[np.argmin(np.linalg.norm(self.dense[win, :2] - np.asarray(xy, np.float64)[:2], axis=1))])
        self.s = float(self.arc[i])
        j = min(int(np.searchsorted(self.arc, self.s + self.lookahead)), len(self.arc) - 1)
        return self.dense[j, :2].copy(), float(self.dense[j, 2])


@dataclass
class DriveTerms(ConfigTerms):
    """The goal-term and structured-drive fields of a driving task's config (flat in it:
    ``--base-w-goal``), and the :class:`DriveGoalCost` and :class:`StructuredDrives` they make."""

    #: weight of the distance to the goal (per metre, per step)
    w_goal: float = bounded(1.0, ge=0)
    #: extra weight of the last step of the goal cost
    terminal_factor: float = bounded(5.0, ge=0)
    #: weight of the smallest distance to the goal along each rollout (min over t; a rollout that
    #: passes close to the goal, e.g. through a doorway and on, is preferred)
    min_factor: float = bounded(5.0, ge=0)
    #: structured samples: straight drives in this many world directions (one is the bearing to
    #: the goal) and the same drives turning to the goal after 1/4, 1/2, 3/4 of the horizon (0 = off)
    n_directions: int = bounded(8, ge=0)
    #: speed of the structured samples (m/s)
    primitive_speed: float = bounded(0.8, ge=0)
    #: turn rate (rad/s) of the structured samples towards their direction of travel
    primitive_turn_rate: float = bounded(1.5, ge=0)
    #: stagnation recovery: when the distance to the goal has not improved for stuck_steps,
    #: sidestep perpendicular to the bearing to the goal, back and forth with doubling sweeps,
    #: until a collision-free rollout gets clearly closer to the goal than ever before (off by
    #: default: see splatplan.tasks.base)
    recovery: bool = False
    #: MPC steps without progress that count as stagnation (goal) or a blocked sweep
    stuck_steps: int = bounded(10, ge=1)
    #: no recovery closer than this to the goal (m): the final approach is slow, not stuck
    recovery_min_distance_m: float = bounded(0.5, ge=0)
    #: progress (m) that resets the stagnation counter
    stuck_progress_m: float = bounded(0.05, ge=0)
    #: length (m) of the first sweep; each reversal sweeps back twice as far
    detour_length_m: float = bounded(2.0, gt=0)
    #: a detour ends when a collision-free rollout gets this much closer (m) to the goal than the
    #: base ever was or any collision-free rollout of goal mode saw before the detour
    detour_exit_margin_m: float = bounded(0.3, ge=0)
    #: side of the first sweep: -1 clockwise (right of the bearing to the goal), +1 counterclockwise
    #: (a fixed convention, like the Bug algorithms' turning direction)
    first_sweep: int = bounded(-1, choices=(-1, 1))
    #: sweeps: weight of the progress along the sweep direction (per metre, per step)
    w_sweep: float = bounded(0.3, ge=0)
    #: sweeps: weight of facing the sweep direction sum_t (1 - cos(yaw_t - heading)) (walk forward)
    w_align: float = bounded(1.0, ge=0)
    #: weight of facing the goal: sum_t (1 - cos(yaw_t - bearing to the goal)) (a walking robot
    #: moves best forward; 0 = off)
    w_heading: float = bounded(0.5, ge=0)

    def goal_cost(self, goal, field=None) -> DriveGoalCost:
        """The :class:`DriveGoalCost` to ``goal`` (2,) (on ``field``, e.g. an ObstacleMemory, when given)."""
        return DriveGoalCost(goal, w_goal=self.w_goal, terminal_factor=self.terminal_factor, min_factor=self.min_factor, w_heading=self.w_heading, w_sweep=self.w_sweep,
                             w_align=self.w_align, field=field)  # fmt: skip

    def drives(self, goal_cost: DriveGoalCost, recovery: bool) -> StructuredDrives:
        """The :class:`StructuredDrives` around ``goal_cost``, with the stagnation recovery when ``recovery``."""
        return StructuredDrives(goal_cost, n_directions=self.n_directions, speed=self.primitive_speed, turn_rate=self.primitive_turn_rate, recovery=recovery,
                                stuck_steps=self.stuck_steps, min_distance_m=self.recovery_min_distance_m, stuck_progress_m=self.stuck_progress_m,
                                detour_length_m=self.detour_length_m, exit_margin_m=self.detour_exit_margin_m, first_sweep=self.first_sweep)  # fmt: skip
