"""Goal-state refinement of a plan (:class:`GoalRefiner`): an elitist evolution strategy with
covariance adaptation over offsets of the plan's state at the goal time, used by the visual
reaching task (:mod:`splatplan.tasks.reach`) between MPPI iterations: near the goal the image cost
is a narrow valley where isotropic knot noise only finds tiny improvements.
"""

from __future__ import annotations

import numpy as np

from ..errors import SplatplanError

__all__ = ["GoalRefiner"]


class GoalRefiner:
    """Elitist evolution strategy with covariance adaptation for the plan's goal-time state.

    Each iteration samples K offsets ``d_k = sigma A z_k`` (``A A^T = C``, ``z_k ~ N(0, I)``, row 0 =
    0: the current plan), and :meth:`update` keeps the cheapest (so the plan never gets worse), adapts
    ``sigma`` to success (x ``grow`` after an improvement, x ``shrink`` otherwise, within
    [``sigma_min``, ``sigma``]) and C with the rank-one and rank-mu updates of CMA-ES (Hansen, "The
    CMA Evolution Strategy: A Tutorial", 2016) from the mu = K / 4 best offsets, normalised to
    det C = 1. Near the goal the image cost is a narrow valley (translating the camera while turning
    it to keep looking at the same point barely changes the view): an isotropic search then only
    accepts tiny steps, the learned C stretches the samples along the valley.
    """

    def __init__(self, dim: int, n_samples: int, sigma: float, *, sigma_min: float = 0.002, grow: float = 1.5, shrink: float = 0.6, rng=None) -> None:
        if n_samples < 2 or not sigma > 0:
            raise SplatplanError(f"GoalRefiner needs n_samples >= 2 and sigma > 0, got {n_samples} and {sigma}")
        self.dim, self.n_samples = int(dim), int(n_samples)
        self.sigma_max, self.sigma_min = float(sigma), float(min(sigma_min, sigma))
        self.sigma, self.grow, self.shrink = float(sigma), float(grow), float(shrink)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.cov = np.eye(self.dim)  # (dim, dim) search shape, det 1
        self.path = np.zeros(self.dim)  # evolution path of the selected steps
        self.mu = max(1, (self.n_samples - 1) // 4)
        w = np.log(self.mu + 0.5) - np.log(np.arange(1, self.mu + 1))
        self.weights = w / w.sum()  # (mu,) recombination weights, best first
        self.mu_eff = 1.0 / float(np.sum(self.weights**2))
        n, me = self.dim, self.mu_eff
        self.c_path = 4.0 / (n + 4.0)
        self.c_one = 2.0 / ((n + 1.3) ** 2 + me)
        self.c_mu = min(1.0 - self.c_one, 2.0 * (me - 2.0 + 1.0 / me) / ((n + 2.0) ** 2 + me))
        self._y = np.zeros((self.n_samples, self.dim))

    def sample(self) -> np.ndarray:
        """(K, dim) offsets; row 0 is 0."""
        a = np.linalg.cholesky(self.cov)
        self._y = self.rng.standard_normal((self.n_samples, self.dim)) @ a.T  # (K, dim) in units of sigma
        self._y[0] = 0.0
        return self.sigma * self._y

    def update(self, offsets: np.ndarray, costs: np.ndarray) -> int:
        """Costs (K,) of the last :meth:`sample`'s offsets -> index of the sample to keep (0 = the plan)."""
        c = np.where(np.isfinite(costs), np.asarray(costs, np.float64), np.inf)
        order = np.argsort(c, kind="stable")
        best = int(order[0]) if c[order[0]] < c[0] else 0
        sel = np.array([i for i in order if i != 0][: self.mu])
        if np.all(np.isfinite(c[sel])):
            y = self._y[sel]  # (mu, dim)
            cp = self.c_path
            self.path = (1.0 - cp) * self.path + np.sqrt(cp * (2.0 - cp) * self.mu_eff) * (self.weights @ y)
            cov = (1.0 - self.c_one - self.c_mu) * self.cov + self.c_one * np.outer(self.path, self.path) + self.c_mu * np.einsum("i,ij,ik->jk", self.weights, y, y)
            ev = np.linalg.eigvalsh(cov)
            if ev[0] > 0:
                self.cov = cov / np.exp(np.mean(np.log(ev)))
        self.sigma = float(np.clip(self.sigma * (self.grow if best else self.shrink), self.sigma_min, self.sigma_max))
        return best
