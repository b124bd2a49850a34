"""The shape every MPPI cost shares: a :class:`Rollout` batch in, (K,) weighted costs out.

:class:`Cost` is the base class of every cost term (:mod:`.costs`, :mod:`.collision_cost`,
:mod:`.image_cost`, the drive costs); :func:`evaluate_costs` sums a list of them as MPPI does.
Rollout arrays: states (K, T, dx) after each control step, controls (K, T, du), ``dt`` seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SplatplanError
from ..metric.config import QueryResult

__all__ = ["Cost", "CostValue", "Rollout", "evaluate_costs", "reduce_time", "total_cost"]


@dataclass
class Rollout:
    """K sampled trajectories of horizon T.

    Attributes:
        states: (K, T, dx) states after each control step (x_1 .. x_T).
        controls: (K, T, du) controls.
        dt: control period (s).
        goal_step: index of the step at the goal time (a shrinking-horizon MPC: T - 1 - s after s
            executed steps); costs that end at the goal time (:class:`ImageCost`,
            :class:`UntilGoalCost`) read it. None = the last step.
        cache: a private memo of the costs (link poses, their collision query) so that several
            costs share them; what a cost reports goes into its :class:`CostValue` instead.
    """

    states: np.ndarray
    controls: np.ndarray
    dt: float
    goal_step: int | None = None
    cache: dict = field(default_factory=dict)

    @property
    def k(self) -> int:
        return int(self.states.shape[0])


def reduce_time(c, k: int, what: str) -> np.ndarray:
    """(K,) or (K, T, ...) costs -> (K,) (summed over everything but K)."""
    c = np.asarray(c, dtype=np.float64)
    if c.shape == (k,):
        return c
    if c.ndim >= 2 and c.shape[0] == k:
        return c.reshape(k, -1).sum(axis=1)
    raise SplatplanError(f"{what} must return (K,) or (K, T) costs for K = {k}, got shape {c.shape}")


@dataclass
class CostValue:
    """What one cost reports on a batch of K rollouts (:meth:`Cost.evaluate`).

    Attributes:
        terms: name -> (K,) weighted terms (summed into the total).
        values: name -> per-sample diagnostics, unweighted (e.g. "image_raw": (K,)).
        query: the collision QueryResult (K, T', L) of a collision cost, else None.
    """

    terms: dict
    values: dict = field(default_factory=dict)
    query: QueryResult | None = None


class Cost:
    """Base class: ``terms(rollout) -> {name: (K,)}``, ``__call__(rollout) -> (K,)`` (weighted);
    ``evaluate(rollout) -> CostValue`` adds what the cost has to report beside its terms."""

    name = "cost"

    def terms(self, rollout: Rollout) -> dict[str, np.ndarray]:
        return {self.name: self(rollout)}

    def evaluate(self, rollout: Rollout) -> CostValue:
        return CostValue(self.terms(rollout))

    def __call__(self, rollout: Rollout) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError



def evaluate_costs(costs: list[Cost], rollout: Rollout) -> tuple[np.ndarray, dict[str, np.ndarray], dict, QueryResult | None]:
    """Sum of a list of costs on one rollout batch: total (K,), {term name: (K,)}, the values they
    report and the first collision query (None without one)."""
    terms: dict[str, np.ndarray] = {}
    values: dict = {}
    query = None
    for c in costs:
        cv = c.evaluate(rollout)
        for name, v in cv.terms.items():
            v = np.asarray(v, dtype=np.float64)
            terms[name] = terms[name] + v if name in terms else v
        values.update(cv.values)
        query = cv.query if query is None else query
    total = np.sum(list(terms.values()), axis=0) if terms else np.zeros(rollout.k)
    return total, terms, values, query


def total_cost(costs: list[Cost], rollout: Rollout) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Sum of a list of costs on one rollout batch: total (K,), {term name: (K,)}."""
    total, terms, _, _ = evaluate_costs(costs, rollout)
    return total, terms
