"""MPPIConfig.elite (opt-in elitism): the step ends on a plan at least as good as every sample it saw."""

from __future__ import annotations

import numpy as np

from splatplan.planners import MPPI, CostWeights, HolonomicPoint, MPPIConfig

START = np.array([0.0, 0.0, 0.06])
GOAL = np.array([0.3, -0.2, 0.06])


def _run(elite: bool, seed: int = 0):
    seen = []  # (K,) terminal costs of every sampled batch (the nominal's own evaluation excluded)

    def terminal(x):  # (K, 3) -> (K,)
        c = np.linalg.norm(x[:, :2] - GOAL[:2], axis=-1)
        if len(x) > 1:
            seen.append(c)
        return c

    # a very high temperature: the weighted mean is nearly the plain sample mean, worse than the best sample
    cfg = MPPIConfig(n_samples=16, horizon=10, n_knots=4, dt=0.1, temperature=1e3, noise_sigma=0.3, n_iters=4,
                     u_min=(-0.5, -0.5, 0.0), u_max=(0.5, 0.5, 0.0), seed=seed, elite=elite)  # fmt: skip
    mppi = MPPI(HolonomicPoint(), None, cfg, terminal_cost=terminal, weights=CostWeights(w_control=0.0))
    _, info = mppi.step(START)
    return info, float(np.min(np.concatenate(seen)))


def test_elite_is_off_by_default():
    assert MPPIConfig().elite is False


def test_elite_step_ends_on_the_best_sample_seen():
    for seed in range(3):
        info, best_seen = _run(True, seed)
        assert info.nominal_cost <= best_seen + 1e-12
        plain, plain_best = _run(False, seed)
        assert plain.nominal_cost > plain_best  # without elitism the averaged plan is worse here
        assert info.nominal_cost < plain.nominal_cost
