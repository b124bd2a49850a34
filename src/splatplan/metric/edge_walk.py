"""Straight configuration-space edges checked by a SLACK WALK (:meth:`CollisionChecker.edges_free`).

An edge a -> b of a robot is checked at samples ``a + (k / n)(b - a)``, k = 1..n (the start is
not checked), where ``step`` (per ellipsoid, scene units) bounds how far any point of the ellipsoid
moves from one sample to the next (a planner's motion bound over the edge divided by n). The edge
is free when every sample is.

**SLACK WALK.** Not every sample is checked. A checked free sample comes back with each ellipsoid's
RIGID SLACK (:meth:`CollisionChecker.collides_configs_slack`): a rigid motion that moves none of
the ellipsoid's points farther keeps it free, so the samples within ``floor(min_e slack_e /
step_e)`` of it are free as well (an ellipsoid that does not move, step 0, is free at all of them).
The walk keeps the prefix 1..lo proven free and checks the sample ``w`` past it, asking for a slack
of ``w`` steps (plus half a step: the checker returns a capped slack a little short of what was
asked; a link whose grid bound falls short reads the splats that far around it, and more steps
read more splats). A check that reaches back to the prefix extends it past its own reach,
and the next one goes one step farther (w + 1, at most ``target_steps``); one that does not leaves
a proven span, and the gap before it is filled from its right end, each check asking for the slack
that would reach the prefix (at most ``target_steps``) and growing the span leftwards where it
falls short. So the walk asks for about the slack the surfaces around it leave, and checks no
sample twice. It stops at the first colliding sample.
Every answer is the one of checking every sample (the skipped ones are proven free by the
checker's promise); near surfaces a check proves up to 2 target_steps + 1 samples.
With ``screen`` > 0 a first pass checks every screen-th sample (no slack) and stops at a hit: an
edge that collides is then found after a few checks wherever it collides, at ~n / screen more
checks for a free one.

On a CPU checker with a :class:`~splatplan.robots.Robot` this is one kernel launch
(:func:`~.wp_metric_kernel.edge_walk_kernel`: one thread per edge, the FK and the per-configuration
check of each sample inside it); elsewhere :func:`walk_edges_ref` runs the same walk from Python,
one checker call per check. Tests compare both, and both with checking every sample.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..robots.robot import Robot

#: the largest sample count of one edge (the kernel counts samples in int32)
MAX_SAMPLES = 2**31 - 2


def edge_inputs(starts, ends, n_samples, step, dof: int, n_ell: int, target_steps, screen=0, validate: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int]:
    """The walk's inputs as (starts (N, dof) float64, ends, n (N,) int64, step (N, E) float64,
    target_steps int, screen int), or a :class:`SplatplanError` naming what is wrong (without
    ``validate``: shapes only, for callers that built the values themselves)."""
    a = np.asarray(starts, dtype=np.float64)
    b = np.asarray(ends, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != dof or b.shape != a.shape:
        raise SplatplanError(f"edges_free: starts and ends must both have shape (N, {dof}), got {a.shape} and {b.shape}")
    if not validate:
        n, st = np.asarray(n_samples, dtype=np.int64), np.asarray(step, dtype=np.float64)
        if n.shape != (len(a),) or st.shape != (len(a), n_ell):
            raise SplatplanError(f"edges_free: n_samples must have shape ({len(a)},) and step ({len(a)}, {n_ell}), got {n.shape} and {st.shape}")
        return a, b, n, st, int(target_steps), int(screen)
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise SplatplanError("edges_free: starts and ends must be finite")
    n_raw = np.asarray(n_samples)
    if n_raw.shape != (len(a),) or not np.issubdtype(n_raw.dtype, np.integer) and not (np.isfinite(n_raw).all() and (n_raw == np.round(n_raw)).all()):
        raise SplatplanError(f"edges_free: n_samples must be ({len(a)},) whole numbers, got shape {n_raw.shape}")
    n = n_raw.astype(np.int64)
    if len(n) and (n.min() < 1 or n.max() > MAX_SAMPLES):
        raise SplatplanError(f"edges_free: n_samples must be in 1..{MAX_SAMPLES}, got {int(n.min())}..{int(n.max())}")
    st = np.asarray(step, dtype=np.float64)
    if st.shape != (len(a), n_ell):
        raise SplatplanError(f"edges_free: step must have shape ({len(a)}, {n_ell}) (per edge, per ellipsoid), got {st.shape}")
    if not np.isfinite(st).all() or (st < 0).any():
        raise SplatplanError("edges_free: step must be finite and >= 0 (scene units)")
    t = float(target_steps)
    if not (math.isfinite(t) and t == int(t) and 1 <= t <= 1024):
        raise SplatplanError(f"edges_free: target_steps must be a whole number in 1..1024, got {target_steps}")
    sc = float(screen)
    if not (math.isfinite(sc) and sc == int(sc) and 0 <= sc <= MAX_SAMPLES):
        raise SplatplanError(f"edges_free: screen must be a whole number >= 0 (0: none), got {screen}")
    return a, b, n, st, int(t), int(sc)


def walk_edges_ref(check: Callable[[np.ndarray, np.ndarray | None], tuple[bool, np.ndarray | None]], starts: np.ndarray, ends: np.ndarray, n: np.ndarray,
                   step: np.ndarray, target_steps: int, screen: int = 0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The SLACK WALK (module docstring) from Python: ``check(q (1, dof) float64, target (1, E) or
    None)`` -> (hit, RIGID SLACK (E,)) checks one configuration (None: no slack asked for, the
    screen's checks). Returns (free (N,) bool, checks (N,) int64)."""
    free = np.ones(len(starts), dtype=bool)
    checks = np.zeros(len(starts), dtype=np.int64)
    t = int(target_steps)
    for i in range(len(starts)):
        a, b, ni, st = starts[i], ends[i], int(n[i]), step[i]
        moving = st > 0
        lo, want, span0, span1 = 0, t, ni + 1, -1
        for ks in range(int(screen), ni, int(screen)) if screen > 0 else ():  # the screen
            checks[i] += 1
            if check((a + (ks / ni) * (b - a))[None], None)[0]:
                free[i], lo = False, ni
                break
        while lo < ni:
            pk = min(lo + 1 + want, ni)
            if span0 <= ni:  # fill the gap before the span from its right end
                pk = span0 - 1
                want = min(t, pk - lo - 1)
            q = a + (pk / ni) * (b - a)
            hit, sl = check(q[None], (st * (want + 0.5 if want > 0 else 0.0))[None])
            checks[i] += 1
            if hit:
                free[i] = False
                break
            reach = float(ni)
            if moving.any():
                reach = min(reach, float(np.floor(np.asarray(sl, dtype=np.float64)[moving] / st[moving]).min()))
            k = int(max(reach, 0.0))
            if pk - k <= lo + 1:
                lo = max(lo, min(pk + k, ni))
                if lo + 1 >= span0:
                    lo, span0 = max(lo, span1), ni + 1
                want = min(t, max(k, want + 1))
            else:  # a new span, or (filling a gap) the span grown leftwards
                span0, span1 = pk - k, (min(pk + k, ni) if span0 > ni else span1)
    return free, checks


def walk_with_checker(checker, robot: Robot, starts: np.ndarray, ends: np.ndarray, n: np.ndarray, step: np.ndarray, target_steps: int,
                      screen: int = 0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """:func:`walk_edges_ref` with ``checker.collides_configs_slack`` (a
    :class:`~.checker.CollisionChecker`) as the check: any backend, device or robot type."""

    def check(q, target):
        if target is None:
            return bool(np.asarray(checker.collides_configs(robot, q)).reshape(-1)[0]), None
        hit, sl = checker.collides_configs_slack(robot, q, rigid_target=target)
        return bool(np.asarray(hit).reshape(-1)[0]), np.asarray(sl).reshape(-1)

    return walk_edges_ref(check, starts, ends, n, step, target_steps, screen)
