"""MPPI with B-spline-parametrised controls and the CollisionSplatting collision cost (paper Sec. II-D).

One MPC step (:meth:`MPPI.step`) runs ``n_iters`` iterations of:

1. sample K control-knot sequences, by default (:class:`GaussianKnots`) ``V_k = U_bar + eps_k``,
   ``eps_k ~ N(0, diag(sigma^2))`` per knot (sample 0 is the unperturbed nominal), clipped to the
   control bounds; a :class:`SamplingStrategy` may sample otherwise (e.g. the planar base's
   structured drives, :mod:`splatplan.planners.drive`);
2. controls ``u_k = B V_k`` (uniform cubic B-spline basis B (T, n_knots), clamped or not:
   ``MPPIConfig.clamped_spline``), so the clipped knots keep every control inside the bounds
   (convex hull property);
3. roll out ``x_k = f(x, u_k)`` (K, T, dx);
4. cost ``C_k = sum_c cost_c(rollout_k)`` over a list of composable cost objects
   (:mod:`splatplan.planners.costs`), reported as a typed :class:`Evaluation`. Built from
   :class:`CostWeights` and the ``task_cost`` / ``terminal_cost`` callables when no list is given:
   ``w_col sum_{t,l} cost_{ktl} + w_hit sum_{t,l} [in collision]_{ktl}`` (:class:`CollisionCost`:
   one query on the (K, T, dof) batch over every robot ellipsoid)
   ``+ w_task task(x_k)`` (:class:`StateCost`) ``+ w_ctrl sum_t |u_kt|^2 dt``
   (:class:`ControlEffortCost`) ``+ w_term terminal(x_kT)`` (:class:`TerminalCost`);
5. weights ``w_k = exp(-(C_k - min C) / lambda) / sum_l exp(-(C_l - min C) / lambda)``;
6. ``U_bar <- sum_k w_k V_k`` (or the knots the strategy's ``select`` returns).

Then the first control of the nominal is returned and the knots are warm-started for the next
step by shifting the curve one control period forward in time (least squares, see
:class:`~splatplan.planners.bspline.UniformBSpline`). The image cost of the paper enters as a cost
object (:class:`~splatplan.planners.image_cost.ImageCost`) or through ``terminal_cost``.

Nothing inside MPPI is changed from outside while it runs: a schedule passes ``n_iters``,
``temperature`` and ``goal_step`` to :meth:`MPPI.step`, scales the noise with
:meth:`MPPI.set_noise_scale` and sets the nominal / noise generator with :meth:`MPPI.reset`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, overload

import numpy as np

from .._config import bounded, check_config
from .._resources import require_rollouts
from ..errors import SplatplanError
from .bspline import UniformBSpline
from .collision_cost import CollisionCost, link_geometry
from .cost_base import Cost, Rollout, evaluate_costs
from .costs import ControlEffortCost, StateCost, TerminalCost
from .dynamics import Dynamics, JointIntegrator

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..metric.config import QueryResult


@dataclass
class MPPIConfig:
    """Algorithm settings of :class:`MPPI` (the cost weights are the costs' own, or
    :class:`CostWeights` for the default cost list). Time in seconds, controls in the dynamics' units."""

    #: number of sampled control sequences K per iteration
    n_samples: int = bounded(256, ge=2)
    #: prediction horizon T (control steps)
    horizon: int = bounded(30, ge=2)
    #: B-spline control points per control dimension over the horizon (>= 4)
    n_knots: int = bounded(6, ge=4)
    #: control period (s); the horizon spans T * dt seconds
    dt: float = bounded(0.1, gt=0)
    #: MPPI temperature lambda: smaller = greedier (weights concentrate on the best samples)
    temperature: float = bounded(1.0, gt=0)
    #: standard deviation of the knot perturbations, one per control dimension (or one for all)
    noise_sigma: float | tuple[float, ...] = bounded(0.1, ge=0)
    #: MPPI iterations per MPC step
    n_iters: int = bounded(3, ge=1)
    #: lower control bound per dimension (or one for all); None = unbounded
    u_min: float | tuple[float, ...] | None = None
    #: upper control bound per dimension (or one for all); None = unbounded
    u_max: float | tuple[float, ...] | None = None
    #: clamped (endpoint-interpolating) B-spline knot vector; False = plain uniform, so that the
    #: applied first control (c0 + 4 c1 + c2) / 6 is set by knots that shape the whole rollout
    #: rather than by c0 alone (see :mod:`splatplan.planners.bspline`)
    clamped_spline: bool = True
    #: after the iterations, cost the updated nominal once more and query its collisions at every
    #: step (``MPPIInfo.nominal_cost``, ``nominal_values``, ``nominal_in_collision``, ``nominal_min_s2``);
    #: False = the info's nominal is its rollout only (one evaluation and one query fewer per step)
    report_nominal: bool = True
    #: seed of the noise generator
    seed: int = bounded(0, ge=0)
    #: prune hopeless samples (opt-in): a sample whose cost is proven to exceed the best complete
    #: sample's by more than ``prune_margin * temperature`` (so its weight is below
    #: exp(-prune_margin) of the best's, e.g. 4e-18 for 40) is not collision-checked to the end.
    #: The collision cost is evaluated in ``prune_chunks`` chunks of the horizon: every sample gets
    #: the first chunk, the ``prune_probe`` cheapest ones all of it (their totals bound the best
    #: cost), the others the next chunk only while their lower bound (every other cost term, exact,
    #: plus the collision terms so far, which are >= 0) stays within the margin. The update equals
    #: the unpruned one to float64 rounding; the costs and terms of pruned samples are those lower
    #: bounds (``Evaluation.n_pruned`` counts them). Needs exactly one CollisionCost among the costs
    #: and n_samples > prune_probe; None = off
    prune_margin: float | None = bounded(None, gt=0)
    #: chunks of the horizon's evaluated steps for ``prune_margin``
    prune_chunks: int = bounded(4, ge=2)
    #: samples (lowest lower bound after the first chunk) evaluated completely to bound the best cost
    prune_probe: int = bounded(4, ge=1)
    #: elitism (opt-in): within one step, sample 1 of every later iteration is the lowest-cost sample
    #: seen so far, and the step ends on it when it beats the updated nominal (one extra evaluation
    #: then); the plan then never gets worse within a step. False = plain MPPI
    elite: bool = False

    def validate(self) -> "MPPIConfig":
        """Check every field's declared range and the cross-field rules (never changes the config); returns self."""
        check_config(self)  # each field's declared range (splatplan._config); cross-field rules below
        require_rollouts(self.n_samples, self.horizon, "MPPIConfig")
        if self.n_samples < 2:
            raise SplatplanError(f"MPPIConfig.n_samples must be >= 2, got {self.n_samples}")
        if self.horizon < 2:
            raise SplatplanError(f"MPPIConfig.horizon must be >= 2, got {self.horizon}")
        if self.n_knots < 4:
            raise SplatplanError(f"MPPIConfig.n_knots must be >= 4 (cubic B-spline), got {self.n_knots}")
        if self.n_knots > self.horizon:
            raise SplatplanError(f"MPPIConfig.n_knots must be <= horizon (knots of a spline over the horizon's steps), got n_knots={self.n_knots}, horizon={self.horizon}")
        if not self.dt > 0 or not self.temperature > 0:
            raise SplatplanError("MPPIConfig.dt and temperature must be > 0")
        if self.n_iters < 1:
            raise SplatplanError(f"MPPIConfig.n_iters must be >= 1, got {self.n_iters}")
        if self.prune_margin is not None and not (np.isfinite(self.prune_margin) and self.prune_margin > 0):
            raise SplatplanError(f"MPPIConfig.prune_margin must be finite and > 0 (or None: off), got {self.prune_margin}")
        if self.prune_chunks < 2 or self.prune_probe < 1:
            raise SplatplanError(f"MPPIConfig.prune_chunks must be >= 2 and prune_probe >= 1, got {self.prune_chunks} and {self.prune_probe}")
        return self


def collision_stride_value(stride: int | str, owner: str = "collision_stride") -> int | str:
    """A collision stride setting as an int >= 1 or "auto" (digits in a string are an int)."""
    if isinstance(stride, str):
        if stride == "auto":
            return stride
        if not stride.isdigit():
            raise SplatplanError(f"{owner} must be an integer >= 1 or 'auto', got {stride!r}")
        stride = int(stride)
    if int(stride) < 1:
        raise SplatplanError(f"{owner} must be >= 1 or 'auto', got {stride}")
    return int(stride)


@dataclass
class CostWeights:
    """Weights of the default cost list of :class:`MPPI` (used when it is given no ``costs``):
    :class:`CollisionCost`, :class:`ControlEffortCost` and the ``task_cost`` / ``terminal_cost``
    callables."""

    #: weight of the collision cost (checker ``cost`` summed over time and links)
    w_collision: float = bounded(1.0, ge=0)
    #: extra cost per (time step, link) in collision (``in_collision``); 0 = the paper's cost only
    w_hit: float = bounded(10.0, ge=0)
    #: weight of the task cost callable
    w_task: float = bounded(1.0, ge=0)
    #: weight of the control effort sum_t |u_t|^2 dt
    w_control: float = bounded(0.01, ge=0)
    #: weight of the terminal cost callable (e.g. the image cost)
    w_terminal: float = bounded(1.0, ge=0)
    #: neighbourhood of the rollouts' collision cost: splats with s2~ below this (the s2_cap of the
    #: collision cost's queries). Beyond it a splat's cost d_max exp(-gamma (s2~ - 1)) is below
    #: exp(-gamma (cap - 1)) (1.8% of d_max for the defaults gamma = 4, cap = 2); a smaller cap is a
    #: much smaller search radius. None = the checker's own s2_cap.
    #: (at most 16: beyond, below exp(-60) of d_max, while the search radius and time grow as sqrt(cap))
    collision_s2_cap: float | None = bounded(2.0, ge=1, le=16)
    #: evaluate the collision cost on every n-th rollout step only (the last always; sums scaled by
    #: n): n times fewer queries, at the risk of stepping over thin obstacles; 1 = every step;
    #: "auto" = the largest n such that no ellipsoid point moves more than collision_max_gap_m
    #: between evaluated steps (from the robot's motion_bound, its speed limits and the control
    #: bounds, times dt; see CollisionCost)
    collision_stride: int | str = 1
    #: gap of collision_stride="auto" (scene units); None = half the smallest moving semi-axis
    collision_max_gap_m: float | None = bounded(None, gt=0)

    def validate(self) -> "CostWeights":
        """Check the declared ranges and the stride (never changes the config); returns self."""
        check_config(self)
        collision_stride_value(self.collision_stride, "CostWeights.collision_stride")
        if self.collision_max_gap_m is not None and not (np.isfinite(self.collision_max_gap_m) and self.collision_max_gap_m > 0):
            raise SplatplanError(f"CostWeights.collision_max_gap_m must be finite and > 0, got {self.collision_max_gap_m}")
        return self


@dataclass
class Evaluation:
    """A batch of K knot sequences rolled out and costed (:meth:`MPPI.evaluate`).

    Attributes:
        total: (K,) total cost of every sample.
        terms: name -> (K,) weighted cost terms (they sum to ``total``).
        values: name -> per-sample diagnostics the costs report beside their terms, unweighted
            (e.g. "image_raw": (K,) the image cost before its weight and log; "goal_distance": (K, T)).
        states: (K, T, dx) rollouts; controls: (K, T, du) their controls.
        query: the collision cost's QueryResult over its evaluated steps, fields (K, T', L), or
            None (no collision cost, or a pruned evaluation).
        n_pruned: samples not collision-checked to the end (``MPPIConfig.prune_margin``; their
            ``total`` and terms are lower bounds).
    """

    total: np.ndarray
    terms: dict
    values: dict
    states: np.ndarray
    controls: np.ndarray
    query: QueryResult | None = None
    n_pruned: int = 0

    def in_collision(self) -> np.ndarray:
        """(K,) bool: some ellipsoid of the sample collides at some evaluated step (False without a query)."""
        if self.query is None:
            return np.zeros(len(self.total), dtype=bool)
        return np.any(np.asarray(self.query.in_collision).reshape(len(self.total), -1), axis=1)


class SamplingStrategy:
    """Extension point of :class:`MPPI`: how the knot sequences of one iteration are sampled, and
    optionally which knots replace the weighted-mean update.

    ``begin_step(mppi, x)`` is called once at the start of every :meth:`MPPI.step` (a strategy
    with state across steps updates it there). ``sample(mppi, x, rng)`` returns (K', n_knots, du) knot sequences (MPPI clips them to the control
    bounds; K' may differ from ``n_samples``), drawing noise only from ``rng`` (MPPI's generator).
    ``select(mppi, x, samples, evaluation)`` may return (n_knots, du) knots to take as the new
    nominal instead of the MPPI weighted mean (None: the weighted mean), e.g. a recovery manoeuvre
    that found a way out.
    """

    def begin_step(self, mppi: "MPPI", x: np.ndarray) -> None:
        return None

    def sample(self, mppi: "MPPI", x: np.ndarray, rng: np.random.Generator) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def select(self, mppi: "MPPI", x: np.ndarray, samples: np.ndarray, evaluation: Evaluation) -> np.ndarray | None:
        return None


class GaussianKnots(SamplingStrategy):
    """The default: ``V_k = U_bar + eps_k``, ``eps_k ~ N(0, diag(sigma^2))`` per knot, K = ``n_samples``,
    sample 0 the unperturbed nominal; sigma is ``MPPIConfig.noise_sigma`` times the current noise
    scale (:meth:`MPPI.set_noise_scale`)."""

    def sample(self, mppi: "MPPI", x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        eps = rng.standard_normal((mppi.config.n_samples, mppi.config.n_knots, mppi.du)) * mppi.sigma  # (K, n, du)
        eps[0] = 0.0  # keep the nominal itself among the samples
        return mppi.knots[None] + eps


@dataclass
class MPPIInfo:
    """Diagnostics of one :meth:`MPPI.step` (arrays from its last iteration unless stated).

    Attributes:
        costs: (K,) total cost of every sample.
        cost_terms: name -> (K,) weighted cost terms ("collision", "hit", "task", "control", "terminal").
        weights: (K,) MPPI weights (sum to 1).
        best_states: (T, dx) rollout of the lowest-cost sample.
        best_cost: its cost.
        nominal_states: (T, dx) rollout of the updated nominal (before the warm-start shift).
        nominal_controls: (T, du) its controls; ``nominal_controls[0]`` is the applied control.
        nominal_knots: (n_knots, du) its control points.
        nominal_in_collision: (T, L) bool, collision state of the nominal trajectory's links
            (all False without ``report_nominal`` or a checker).
        nominal_min_s2: (T, L) conservative min scaling distance along the nominal trajectory (inf then).
        nominal_cost: total cost of the nominal (same terms as ``costs``; NaN without ``report_nominal``).
        nominal_values: the values the costs reported on the nominal (see :class:`Evaluation`).
        evaluation: the :class:`Evaluation` of the last iteration's samples.
        time_s: wall-clock seconds of the step.
        n_pruned: samples of the last iteration not collision-checked to the end
            (``MPPIConfig.prune_margin``; their ``costs`` are lower bounds).
    """

    costs: np.ndarray
    cost_terms: dict
    weights: np.ndarray
    best_states: np.ndarray
    best_cost: float
    nominal_states: np.ndarray
    nominal_controls: np.ndarray
    nominal_knots: np.ndarray
    nominal_in_collision: np.ndarray
    nominal_min_s2: np.ndarray
    nominal_cost: float
    nominal_values: dict = field(default_factory=dict)
    evaluation: Evaluation | None = None
    time_s: float = 0.0
    n_pruned: int = 0

    @property
    def nominal_collides(self) -> bool:
        """Whether any link of the nominal trajectory is in collision at any step."""
        return bool(np.any(self.nominal_in_collision))


@overload
def _per_dim(v: None, du: int, name: str) -> None: ...
@overload
def _per_dim(v: float | tuple[float, ...] | np.ndarray, du: int, name: str) -> np.ndarray: ...
def _per_dim(v, du: int, name: str) -> np.ndarray | None:
    if v is None:
        return None
    a = np.broadcast_to(np.asarray(v, dtype=np.float64), (du,)) if np.ndim(v) == 0 else np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (du,):
        raise SplatplanError(f"MPPIConfig.{name} needs 1 or {du} values, got {np.shape(v)}")
    return a.copy()


def mppi_weights(costs: np.ndarray, temperature: float) -> np.ndarray:
    """MPPI weights (K,) of sample costs (K,): exp(-(c - min c) / temperature), normalised to sum
    to 1; non-finite costs weigh 0. The update is ``einsum("k,knd->nd", w, samples)``."""
    c = np.where(np.isfinite(costs), costs, np.inf)
    w = np.exp(-(c - float(np.min(c))) / temperature)
    return w / w.sum()


def joint_speed_bound(dynamics: Dynamics, u_min, u_max) -> np.ndarray | None:
    """(dof,) bound on |dq/dt| of a :class:`JointIntegrator` whose controls (joint velocities) are
    clipped to [u_min, u_max] (per dim or one for all; the B-spline stays inside the knots' bounds)
    and to its ``v_max``; None for other dynamics (the collision cost then derives its own)."""
    if not isinstance(dynamics, JointIntegrator):
        return None
    du = int(dynamics.control_dim)
    v = np.full(du, np.inf) if dynamics.v_max is None else np.asarray(dynamics.v_max, dtype=np.float64).copy()
    lo, hi = _per_dim(u_min, du, "u_min"), _per_dim(u_max, du, "u_max")
    if lo is not None and hi is not None:
        v = np.minimum(v, np.maximum(np.abs(lo), np.abs(hi)))
    if not np.all(np.isfinite(v)):
        raise SplatplanError("collision_stride='auto' needs bounded joint speeds: give u_min/u_max or velocity limits")
    return v


class MPPI:
    """Sampling-based MPC over B-spline control knots (see the module docstring).

    Args:
        dynamics: a :class:`~splatplan.planners.dynamics.Dynamics` (rollout + link_poses).
        checker: a :class:`~splatplan.metric.CollisionChecker` (any backend) for the default
            collision cost and the nominal's collision report; None = neither (a
            :class:`CollisionCost` in ``costs`` still works: it carries its own checker).
        config: :class:`MPPIConfig` (algorithm settings).
        task_cost: states (K, T, dx) -> (K,) or (K, T) (summed over time) geometric task cost
            (wrapped in a :class:`StateCost` of weight ``weights.w_task``).
        terminal_cost: terminal states (K, dx) -> (K,) cost (e.g. the image cost), or None
            (wrapped in a :class:`TerminalCost` of weight ``weights.w_terminal``).
        costs: the cost objects to sum (weights inside each); None = built from ``weights``:
            :class:`CollisionCost` (``w_collision``, ``w_hit``, ``collision_s2_cap``,
            ``collision_stride``; when a checker is given), :class:`ControlEffortCost`
            (``w_control``). ``task_cost`` / ``terminal_cost`` are appended in both cases.
        weights: :class:`CostWeights` of the default cost list and the two callables.
        sampler: the :class:`SamplingStrategy` (default :class:`GaussianKnots`).

    Per-call settings (a documented contract, instead of changing attributes mid-run):
    :meth:`step` takes ``n_iters``, ``temperature`` and ``goal_step`` for that step only,
    :meth:`set_noise_scale` scales the knot noise from now on, :meth:`reset` sets the nominal and
    optionally the noise generator.
    """

    def __init__(
        self,
        dynamics: Dynamics,
        checker: CollisionChecker | None,
        config: MPPIConfig | None = None,
        task_cost: Callable[[np.ndarray], np.ndarray] | None = None,
        terminal_cost: Callable[[np.ndarray], np.ndarray] | None = None,
        costs: list[Cost] | None = None,
        weights: CostWeights | None = None,
        sampler: SamplingStrategy | None = None,
    ) -> None:
        self.dynamics = dynamics
        self.config = (config or MPPIConfig()).validate()
        cfg = self.config
        wts = (weights or CostWeights()).validate()
        self.checker = checker
        self.task_cost = task_cost
        self.terminal_cost = terminal_cost
        du = int(dynamics.control_dim)
        if costs is None:
            costs = []
            if checker is not None and (wts.w_collision > 0 or wts.w_hit > 0):
                stride = collision_stride_value(wts.collision_stride, "CostWeights.collision_stride")
                auto = stride == "auto"
                costs.append(
                    CollisionCost(
                        checker, dynamics if auto else link_geometry(dynamics), weight=wts.w_collision, hit_weight=wts.w_hit, s2_cap=wts.collision_s2_cap,
                        time_stride=stride, max_gap_m=wts.collision_max_gap_m,
                        speed_bound=joint_speed_bound(dynamics, cfg.u_min, cfg.u_max) if auto else None,
                    )
                )  # fmt: skip
            costs.append(ControlEffortCost(wts.w_control))
        else:
            costs = list(costs)
        if task_cost is not None:
            costs.append(StateCost(task_cost, wts.w_task))
        if terminal_cost is not None:
            costs.append(TerminalCost(terminal_cost, wts.w_terminal))
        #: the cost objects summed by :meth:`evaluate`
        self.costs = costs
        cols = [c for c in costs if isinstance(c, CollisionCost)]
        # the nominal's collision report: the collision cost's own checker (its cap), else the checker as given
        self._report = (cols[0].checker, cols[0].geometry) if cols else ((checker, link_geometry(dynamics)) if checker is not None else None)
        self.sampler = sampler if sampler is not None else GaussianKnots()
        self.du = du
        self.noise_sigma = _per_dim(cfg.noise_sigma, du, "noise_sigma")  # (du,) the configured std
        self.sigma = self.noise_sigma.copy()  # (du,) the current std (set_noise_scale)
        self.u_min = _per_dim(cfg.u_min, du, "u_min")
        self.u_max = _per_dim(cfg.u_max, du, "u_max")
        self.spline = UniformBSpline(cfg.n_knots, cfg.horizon, clamped=cfg.clamped_spline)
        self.rng = np.random.default_rng(cfg.seed)
        self.knots = self._clip(np.zeros((cfg.n_knots, du)))  # (n_knots, du) nominal

    # ------------------------------------------------------------------ helpers
    def _clip(self, knots: np.ndarray) -> np.ndarray:
        if self.u_min is not None:
            knots = np.maximum(knots, self.u_min)
        if self.u_max is not None:
            knots = np.minimum(knots, self.u_max)
        return knots

    def clip(self, knots: np.ndarray) -> np.ndarray:
        """Knots (..., n_knots, du) clipped to the control bounds."""
        return self._clip(np.asarray(knots, dtype=np.float64))

    def reset(self, knots: np.ndarray | None = None, rng: np.random.Generator | int | None = None) -> None:
        """Set the nominal control knots (n_knots, du) (zeros when None), clipped to the bounds; with
        ``rng`` (a Generator, used as is, or a seed) also the noise generator."""
        k = np.zeros((self.config.n_knots, self.du)) if knots is None else np.asarray(knots, dtype=np.float64).reshape(self.config.n_knots, self.du)
        self.knots = self._clip(k)
        if rng is not None:
            self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)

    def set_noise_scale(self, *factors: float) -> None:
        """From now on the knot noise std is ``noise_sigma * factors[0] * factors[1] * ...``
        (multiplied in this order; none = the configured std)."""
        s = self.noise_sigma
        for f in factors:
            s = s * float(f)
        self.sigma = np.array(s, dtype=np.float64, copy=True)

    def evaluate(self, x: np.ndarray, knots: np.ndarray, goal_step: int | None = None) -> Evaluation:
        """Roll out and cost a batch of knot sequences.

        Args:
            x: current state (dx,).
            knots: (K, n_knots, du) control points.
            goal_step: index of the rollout step at the goal time (:attr:`Rollout.goal_step`:
                shrinking-horizon costs end there); None = the last step.

        Returns:
            an :class:`Evaluation`.
        """
        cfg = self.config
        controls = self.spline(knots)  # (K, T, du)
        states = self.dynamics.rollout(x, controls, cfg.dt)  # (K, T, dx)
        rollout = Rollout(states, controls, cfg.dt, goal_step=goal_step)
        cols = [c for c in self.costs if isinstance(c, CollisionCost)]
        if cfg.prune_margin is not None and len(cols) == 1 and rollout.k > cfg.prune_probe:
            total, terms, values, n_pruned = self._pruned_cost(rollout, cols[0])
            return Evaluation(total, terms, values, states, controls, None, n_pruned)
        total, terms, values, query = evaluate_costs(self.costs, rollout)
        return Evaluation(total, terms, values, states, controls, query, 0)

    def _pruned_cost(self, rollout: Rollout, col: CollisionCost) -> tuple[np.ndarray, dict, dict, int]:
        """total (K,), terms, values and the pruned count of a batch with hopeless samples pruned
        (see ``MPPIConfig.prune_margin``)."""
        cfg = self.config
        assert cfg.prune_margin is not None  # (the caller prunes only with a margin)
        k, t_len = rollout.k, rollout.states.shape[1]
        base, terms, values, _ = evaluate_costs([c for c in self.costs if c is not col], rollout)  # every other term, exact
        for name, v in col.self_terms(rollout).items():
            base = base + v
            terms[name] = v
        steps = col.steps(t_len, rollout.dt)
        scale = float(col.stride(rollout.dt, t_len))
        chunks = np.array_split(steps, min(cfg.prune_chunks, len(steps)))
        coll = {"collision": np.zeros(k), "hit": np.zeros(k)}

        def add(idx: np.ndarray, chunk: np.ndarray) -> None:
            for name, v in col.chunk_terms(rollout.states[idx][:, chunk], scale).items():
                coll[name][idx] += v

        def lower() -> np.ndarray:
            """(K,) lower bounds of the costs: the collision terms so far are >= 0 (exact once complete)."""
            return base + coll["collision"] + coll["hit"]

        add(np.arange(k), chunks[0])
        probe = np.argsort(lower(), kind="stable")[: cfg.prune_probe]
        for chunk in chunks[1:]:
            add(probe, chunk)
        best = float(np.min(lower()[probe]))  # >= the best cost
        alive = np.ones(k, dtype=bool)
        alive[probe] = False
        for chunk in chunks[1:]:
            alive &= lower() <= best + cfg.prune_margin * cfg.temperature
            idx = np.flatnonzero(alive)
            if idx.size:
                add(idx, chunk)
        terms.update(coll)
        return lower(), terms, values, int(k - cfg.prune_probe - alive.sum())

    # ------------------------------------------------------------------ MPC step
    def step(self, x, *, n_iters: int | None = None, temperature: float | None = None, goal_step: int | None = None) -> tuple[np.ndarray, MPPIInfo]:
        """One MPC step from state ``x`` (dx,): MPPI iterations, then warm start.

        Args:
            x: current state (dx,).
            n_iters: iterations of this step (default ``config.n_iters``).
            temperature: temperature of this step (default ``config.temperature``).
            goal_step: rollout step at the goal time for this step's evaluations (see :meth:`evaluate`).

        Returns:
            u0 (du,): the control to apply now, and an :class:`MPPIInfo`.
        """
        t0 = time.perf_counter()
        cfg = self.config
        n_iters = cfg.n_iters if n_iters is None else int(n_iters)
        lam = cfg.temperature if temperature is None else float(temperature)
        if n_iters < 1 or not lam > 0:
            raise SplatplanError(f"MPPI.step needs n_iters >= 1 and temperature > 0, got {n_iters} and {lam}")
        x = np.asarray(x, dtype=np.float64).reshape(-1)
        self.sampler.begin_step(self, x)
        elite_knots, elite_cost = None, np.inf  # (n, du) lowest-cost sample of this step (cfg.elite)
        for _ in range(n_iters):
            samples = self._clip(self.sampler.sample(self, x, self.rng))  # (K, n, du)
            if elite_knots is not None:
                samples[1] = elite_knots  # the best sample so far competes again
            ev = self.evaluate(x, samples, goal_step)
            c = np.where(np.isfinite(ev.total), ev.total, np.inf)
            cmin = float(np.min(c))
            if cfg.elite and cmin < elite_cost:
                elite_knots, elite_cost = samples[int(np.argmin(c))].copy(), cmin
            w = mppi_weights(c, lam)  # (K,)
            chosen = self.sampler.select(self, x, samples, ev)
            self.knots = self._clip(np.einsum("k,knd->nd", w, samples) if chosen is None else chosen)
        info = self._info(x, ev, w, elite_knots, elite_cost, goal_step)
        u0 = info.nominal_controls[0].copy()
        self.knots = self._clip(self.spline.shift(self.knots))  # warm start: shift by one period
        info.time_s = time.perf_counter() - t0
        return u0, info

    def _info(self, x: np.ndarray, ev: Evaluation, w: np.ndarray, elite_knots, elite_cost: float, goal_step: int | None) -> MPPIInfo:
        """The step's :class:`MPPIInfo` (evaluates the nominal when ``report_nominal`` or elitism needs it)."""
        cfg = self.config
        best = int(np.argmin(np.where(np.isfinite(ev.total), ev.total, np.inf)))
        nom = None
        if cfg.report_nominal or elite_knots is not None:
            nom = self.evaluate(x, self.knots[None], goal_step)
            if elite_knots is not None and elite_cost < float(nom.total[0]):
                self.knots = elite_knots  # the weighted mean is worse than the best sample seen: keep that
                nom = self.evaluate(x, self.knots[None], goal_step)
        if nom is None:
            controls = self.spline(self.knots[None])  # (1, T, du)
            nom_states, nom_controls, nom_cost, values = self.dynamics.rollout(x, controls, cfg.dt)[0], controls[0], float("nan"), {}
        else:
            nom_states, nom_controls, nom_cost, values = nom.states[0], nom.controls[0], float(nom.total[0]), nom.values
        res = None if nom is None else nom.query
        if cfg.report_nominal and self._report is not None and (res is None or res.min_s2.shape[1] != cfg.horizon):
            # collision terms off (or evaluated on a time stride): still report every step
            checker, geometry = self._report
            res = geometry.query(checker, nom_states[None])  # (1, T, L)
        if not cfg.report_nominal:
            res = None
        n_links = 1 if res is None else res.min_s2.shape[-1]
        return MPPIInfo(
            costs=ev.total, cost_terms=ev.terms, weights=w, best_states=ev.states[best], best_cost=float(ev.total[best]),
            nominal_states=nom_states, nominal_controls=nom_controls, nominal_knots=self.knots.copy(),
            nominal_in_collision=np.zeros((cfg.horizon, n_links), dtype=bool) if res is None else res.in_collision[0],
            nominal_min_s2=np.full((cfg.horizon, n_links), np.inf) if res is None else res.min_s2[0],
            nominal_cost=nom_cost, nominal_values=values, evaluation=ev, n_pruned=ev.n_pruned,
        )  # fmt: skip

    def run(
        self,
        x0,
        n_steps: int,
        stop: Callable[[np.ndarray], bool] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, list[MPPIInfo]]:
        """Closed loop on the model itself: apply each step's u0 for ``dt`` with ``dynamics.rollout``.

        Args:
            x0: start state (dx,).
            n_steps: maximum number of MPC steps.
            stop: optional predicate on the current state; the loop ends when it returns True.

        Returns:
            states (S + 1, dx) including x0, controls (S, du), the per-step infos.
        """
        x = np.asarray(x0, dtype=np.float64).reshape(-1)
        xs, us, infos = [x], [], []
        for _ in range(int(n_steps)):
            if stop is not None and stop(x):
                break
            u, info = self.step(x)
            x = self.dynamics.rollout(x, u[None, None, :], self.config.dt)[0, 0]
            xs.append(x)
            us.append(u)
            infos.append(info)
        return np.asarray(xs), np.asarray(us).reshape(-1, self.du), infos
