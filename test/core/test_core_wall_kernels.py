"""The walls' compiled crossing bounds (core/wall_kernels.py) against high-precision oracles.

The oracle is the reflection principle's bound written out in mpmath at 50 digits, in its own
form (``exp(2 a x0 / walk) Phi(-u)``, not through ``erfcx``), and the largest accepted speed is
that oracle's root found by bisection in mpmath: nothing of the kernels is reused.
"""

import math

import mpmath
import numpy as np
import pytest

from prvo_planner.core.special_kernels import erfcx
from prvo_planner.core.wall_kernels import crossing_bounds, line_speeds

mpmath.mp.dps = 50


def exact_bound(mean0, std0, walk, horizon, approach):
    """``P(min over [0, horizon] of y0 - approach t + W(t) < 0)``'s bound, in mpmath.

    ``y0 ~ N(mean0, std0^2)``, ``W`` a Brownian motion of variance WALK per second. Without a
    walk the first term alone (the path is straight); with one, ``y`` is a Brownian motion
    started at ``x0 = mean0 + approach t0`` at ``-t0 = -std0^2 / walk``, and its first passage
    below 0 by the horizon has the reflection principle's probability; ``x0 <= 0``: 1.
    """
    mean0, std0, walk, horizon, approach = (mpmath.mpf(value) for value in
                                            (mean0, std0, walk, horizon, approach))
    spread = mpmath.sqrt(std0 ** 2 + walk * horizon)
    reach = mean0 - approach * horizon
    if spread == 0:
        first = mpmath.mpf(0) if reach >= 0 else mpmath.mpf(1)
    else:
        first = mpmath.ncdf(-reach / spread)
    if walk == 0:
        return first
    before = std0 ** 2 / walk
    start = mean0 + approach * before
    if start <= 0:
        return mpmath.mpf(1)
    far = mean0 + approach * (horizon + 2 * before)
    reflected = mpmath.exp(2 * approach * start / walk) * mpmath.ncdf(-far / spread)
    return min(first + reflected, mpmath.mpf(1))


def relative_error(exact):
    """Return the error allowed relative to a bound: 1e-13, 1e-10 in tails beyond 1e-30.

    A tail ``Phi(-x)`` inherits the rounding of ``x`` amplified by ``d log Phi / dx``, about
    ``x``: ``x^2 2^-53`` relative. At the risks planned with (above 1e-9, x below 6) that is
    far below 1e-13; a bound of 1e-213 (x near 31) is off by 1.6e-13 of itself.
    """
    return 1e-13 if exact >= 1e-30 else 1e-10


def conditions(rng, count):
    """Return COUNT random conditions: mean0, std0, walk (K,) and a horizon, as the walls make."""
    mean0 = rng.uniform(-0.2, 3.0, count)
    std0 = rng.choice([0.0, 0.01, 0.05, 0.1, 0.2], count) * rng.uniform(0.5, 1.0, count)
    walk = 0.1 * rng.choice([0.0, 0.001, 0.01, 0.03], count) * rng.uniform(0.5, 1.0, count)
    return mean0, std0, walk, 2.0


def test_erfcx_is_exp_x_squared_times_erfc_to_a_few_ulps():
    """Across its switch to the continued fraction at 26 and up to 1e6, from mpmath."""
    for value in np.concatenate([np.linspace(0.0, 30.0, 3001), np.geomspace(30.0, 1e6, 200),
                                 np.nextafter(26.0, [0.0, 30.0])]):
        exact = mpmath.exp(mpmath.mpf(value) ** 2) * mpmath.erfc(mpmath.mpf(value))
        assert abs(erfcx(value) - exact) <= 1e-15 * exact, value
    assert math.isnan(erfcx(math.nan))


@pytest.mark.parametrize('seed', range(4))
def test_crossing_bounds_are_the_reflection_principle_bound(seed):
    """Every case: with and without a walk or a spread, approaching or not, x0 <= 0."""
    rng = np.random.default_rng(seed)
    mean0, std0, walk, horizon = conditions(rng, 400)
    approach = np.where(rng.uniform(size=400) < 0.2, 0.0, rng.uniform(0.0, 2.0, 400))
    bounds = crossing_bounds(mean0, std0, walk, horizon, approach)
    for index, bound in enumerate(bounds):
        exact = exact_bound(mean0[index], std0[index], walk[index], horizon, approach[index])
        assert 0.0 <= bound <= 1.0
        assert abs(bound - exact) <= relative_error(exact) * exact + 1e-300, (index, bound)


@pytest.mark.parametrize('seed', range(4))
def test_the_largest_accepted_speed_is_the_bound_s_root(seed):
    """``bound(approach) <= risk`` always, and ``approach`` is the root to within 1e-7 m/s."""
    rng = np.random.default_rng(seed)
    count = 200
    mean0, std0, walk, horizon = conditions(rng, count)
    risks = rng.choice([0.2, 0.05, 1e-3, 1e-6], count)
    # The planner's bracket: the first term's thresholds at half the risk and at the risk.
    spread = np.sqrt(std0 * std0 + walk * horizon)
    quantile = np.vectorize(lambda p: float(-mpmath.sqrt(2) * mpmath.erfinv(1 - 2 * p)))
    low = np.maximum(mean0 + quantile(0.5 * risks) * spread, 0.0) / horizon
    high = np.maximum(mean0 + quantile(risks) * spread, 0.0) / horizon
    still, approach = line_speeds(mean0, std0, walk, horizon, risks, low, high)
    for index in range(count):
        arguments = mean0[index], std0[index], walk[index], horizon
        exact_still = exact_bound(*arguments, 0.0)
        assert abs(still[index] - exact_still) <= relative_error(exact_still) * exact_still \
            + 1e-300
        if not exact_still < risks[index]:
            assert approach[index] == -math.inf
            continue
        assert exact_bound(*arguments, approach[index]) <= risks[index] * (1.0 + 1e-12)
        # Bisection on the oracle: the largest speed whose bound is at most the risk.
        lower, upper = mpmath.mpf(0), mpmath.mpf(5)
        if exact_bound(*arguments, lower) > risks[index]:
            upper = lower
        while upper - lower > 1e-10:
            middle = (lower + upper) / 2
            lower, upper = ((middle, upper) if exact_bound(*arguments, middle) <= risks[index]
                            else (lower, middle))
        assert approach[index] == pytest.approx(float(lower), abs=1e-7)
