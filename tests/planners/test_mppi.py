"""MPPI over B-spline knots: reaches a goal around an obstacle without collisions; API contracts."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners import MPPI, CostWeights, HolonomicPoint, MPPIConfig, PlanarBase, SamplingStrategy

from .scenes import make_checker, make_scene

START = np.array([-0.15, 0.0, 0.06])
GOAL = np.array([0.15, 0.0, 0.06])


@pytest.fixture(scope="module")
def checker():
    # a pillar right on the straight line from START to GOAL
    return make_checker(make_scene([((-0.03, -0.04, 0.0), (0.03, 0.06, 0.12))]), n_sigma=1.0)


def _cfg(**kw):
    base = dict(n_samples=128, horizon=20, n_knots=5, dt=0.1, temperature=0.05, noise_sigma=0.1, n_iters=2,
                u_min=(-0.2, -0.2, 0.0), u_max=(0.2, 0.2, 0.0), w_control=0.0, seed=0)
    base.update(kw)
    return MPPIConfig(**{k: v for k, v in base.items() if k not in WEIGHTS}), CostWeights(**{k: v for k, v in base.items() if k in WEIGHTS})


WEIGHTS = {f.name for f in dataclasses.fields(CostWeights)}


def test_holonomic_point_reaches_goal_around_obstacle(checker):
    cfg, w = _cfg()
    mppi = MPPI(HolonomicPoint(), checker, cfg, task_cost=lambda s: np.linalg.norm(s - GOAL, axis=-1), weights=w)
    xs, us, infos = mppi.run(START, 80, stop=lambda x: np.linalg.norm(x - GOAL) < 0.01)
    assert np.linalg.norm(xs[-1] - GOAL) < 0.01
    assert not checker.collides(xs, None, (0.015, 0.015, 0.015)).any()  # HolonomicPoint()'s sphere
    # it went around the pillar, not through it
    assert np.abs(xs[:, 1]).max() > 0.05
    assert np.all(np.abs(us) <= 0.2 + 1e-12)  # bounds hold through the B-spline convex hull
    np.testing.assert_allclose(xs[:, 2], 0.06)  # zero z-velocity bounds freeze z
    info = infos[0]
    assert info.costs.shape == (128,) and abs(info.weights.sum() - 1) < 1e-9
    assert info.nominal_states.shape == (20, 3) and info.nominal_controls.shape == (20, 3)
    assert info.nominal_in_collision.shape == (20, 1) and info.nominal_min_s2.shape == (20, 1)
    assert set(info.cost_terms) == {"collision", "hit", "task", "control"}
    assert not any(i.nominal_collides for i in infos)


def test_without_collision_cost_it_goes_straight_through(checker):
    cfg, w = _cfg(w_collision=0.0, w_hit=0.0)
    mppi = MPPI(HolonomicPoint(), checker, cfg, task_cost=lambda s: np.linalg.norm(s - GOAL, axis=-1), weights=w)
    xs, _, infos = mppi.run(START, 40, stop=lambda x: np.linalg.norm(x - GOAL) < 0.01)
    assert checker.collides(xs, None, (0.015, 0.015, 0.015)).any()  # the ablation: collisions without the collision cost
    assert any(i.nominal_collides for i in infos)


def test_terminal_cost_hook_and_planar_base(checker):
    seen = []

    def terminal(xt):
        seen.append(xt.shape)
        return np.linalg.norm(xt[:, :2] - GOAL[:2], axis=-1) * 10

    cfg, w = _cfg(u_min=(-0.2, -0.1, -1.0), u_max=(0.2, 0.1, 1.0), noise_sigma=(0.1, 0.05, 0.5))
    mppi = MPPI(PlanarBase(height=0.06), checker, cfg, terminal_cost=terminal, weights=w)
    u, info = mppi.step(np.array([-0.15, -0.15, 0.0]))
    assert (128, 3) in seen and u.shape == (3,)
    assert "terminal" in info.cost_terms and info.nominal_in_collision.shape == (20, 1)


def test_bad_config():
    with pytest.raises(SplatplanError):
        MPPIConfig(n_knots=3).validate()
    with pytest.raises(SplatplanError):
        MPPI(HolonomicPoint(), None, MPPIConfig(noise_sigma=(0.1, 0.1)))
    mppi = MPPI(HolonomicPoint(), None, MPPIConfig(n_samples=8, horizon=5, n_knots=4), task_cost=lambda s: np.zeros((3, 3)))
    with pytest.raises(SplatplanError, match="task_cost"):
        mppi.step(START)


def test_validate_does_not_change_the_config():
    w = CostWeights(collision_stride="3")
    assert w.validate().collision_stride == "3"  # read as 3 by the collision cost, never rewritten
    cfg = MPPIConfig(n_samples=8, horizon=5, n_knots=4)
    before = dataclasses.asdict(cfg)
    cfg.validate()
    assert dataclasses.asdict(cfg) == before


class _Fixed(SamplingStrategy):
    """Samples the nominal and fixed offsets; selects sample 2 in place of the weighted mean."""

    def sample(self, mppi, x, rng):
        off = np.zeros((4, mppi.config.n_knots, mppi.du))
        off[1:, :, 0] = [[0.1], [0.2], [-0.1]]
        return mppi.knots[None] + off

    def select(self, mppi, x, samples, evaluation):
        assert evaluation.total.shape == (4,) and evaluation.states.shape[0] == 4
        return samples[2]


def test_sampling_strategy_and_per_call_settings(checker):
    cfg, w = _cfg(n_samples=4, n_iters=1, report_nominal=False)
    mppi = MPPI(HolonomicPoint(), checker, cfg, task_cost=lambda s: np.linalg.norm(s - GOAL, axis=-1), weights=w, sampler=_Fixed())
    u, info = mppi.step(START)
    np.testing.assert_allclose(info.nominal_knots[:, 0], 0.2)  # the strategy's selection, clipped to u_max = 0.2
    assert np.isnan(info.nominal_cost) and info.evaluation.query is not None and info.evaluation.in_collision().shape == (4,)
    # per-call settings leave the config alone; the noise scale multiplies the configured std in order
    g = MPPI(HolonomicPoint(), None, _cfg()[0], task_cost=lambda s: np.linalg.norm(s - GOAL, axis=-1))
    g.set_noise_scale(0.5, 0.2)
    np.testing.assert_allclose(g.sigma, 0.1 * 0.5 * 0.2)
    g.step(START, n_iters=1, temperature=0.5)
    assert g.config.n_iters == 2 and g.config.temperature == 0.05
    g.reset(rng=7)
    a = g.rng.standard_normal(3)
    g.reset(rng=7)
    np.testing.assert_array_equal(a, g.rng.standard_normal(3))
