"""
The walls' crossing bounds compiled (:mod:`.walls`): every condition's failure bound and speed.

A linear condition ``y(t) = n.p(t) - c >= 0`` over the horizon fails with probability at most
the reflection principle's bound (:func:`crossing_bounds`); on a ray, the condition accepts
speeds towards its line up to the largest one whose bound is at most its risk
(:func:`line_speeds`). Both are arithmetic per condition (a handful of normal tails, eight
steps of regula falsi), which numpy did as tens of calls on arrays of a few hundred elements:
here each condition is one loop iteration in scalars. Two functions, compiled for one signature
each when this module is first imported (:mod:`.walls` imports it on its first model) and kept
in numba's on-disk cache, as the ray search and the certificate are (``./run.sh setup``
compiles all three modules once after installing).

``Phi`` and ``erfcx`` are :mod:`.special_kernels`' (scipy's ufuncs cannot be called from numba):
``Phi`` within 2e-14 of scipy's, ``erfcx`` within a few ulps, so a bound moves by rounding only.
"""

import math

from numba import types

from .ray_solver import jit
from .special_kernels import erfcx, ndtr

_SQRT2 = math.sqrt(2.0)
# Steps of regula falsi (Illinois) for the largest speed towards a line a condition accepts:
# the bracket is already (z(delta / 2) - z(delta)) S / tau wide (a few mm/s) and the bound is
# smooth and monotone in it, so a few steps leave it far below any speed's meaning.
_FALSI_STEPS = 8

_VECTOR = types.float64[::1]
_BOUNDS_SIGNATURE = _VECTOR(_VECTOR, _VECTOR, _VECTOR, types.float64, _VECTOR)
_SPEEDS_SIGNATURE = types.Tuple((_VECTOR, _VECTOR))(
    _VECTOR, _VECTOR, _VECTOR, types.float64, _VECTOR, _VECTOR, _VECTOR)


@jit(inline='always')
def _below_zero(mean, std):
    """``P(N(mean, std^2) < 0)``; a known value (std 0) gives 0 or 1."""
    if std > 0.0:
        return ndtr(-(mean / std))
    return 0.0 if mean >= 0.0 else 1.0


@jit(inline='always')
def _crossing_bound(mean0, std0, walk, horizon, approach):
    """
    Bound on ``P(min over [0, horizon] of y(t) < 0)`` for ``y(t) = y0 - approach t + W(t)``.

    ``y0 ~ N(mean0, std0^2)`` and ``W`` a Brownian motion of variance ``walk`` per second,
    independent of ``y0``; ``approach >= 0``. With ``t0 = std0^2 / walk``, ``y`` on
    ``[0, horizon]`` is the restriction of a Brownian motion with the same drift started at
    ``x0 = mean0 + approach t0`` at time ``-t0``, so the reflection principle over
    ``[-t0, horizon]`` bounds it:
    ``Phi(-(mean0 - approach horizon) / S) + exp(2 approach x0 / walk) Phi(-u)``, with
    ``S^2 = std0^2 + walk horizon`` and ``u = (mean0 + approach (horizon + 2 t0)) / S``. The
    second term is computed as ``phi((mean0 - approach horizon) / S) sqrt(pi / 2)
    erfcx(u / sqrt(2))`` (the same number, without the overflow). Without a walk the path is
    straight and the bound is exact: ``P(y0 < approach horizon)``. In [0, 1].
    """
    reach = mean0 - approach * horizon
    spread = math.sqrt(std0 * std0 + walk * horizon)
    first = _below_zero(reach, spread)
    if not walk > 0.0:
        return first
    before = std0 * std0 / walk
    if not mean0 + approach * before > 0.0:
        # x0 <= 0: the walk starts on the wrong side of the line.
        return 1.0
    # Only a drift towards the line makes u depend on t0 (inf for a vanishing walk).
    far = mean0 + (approach * (horizon + 2.0 * before) if approach > 0.0 else 0.0)
    ratio = reach / spread
    # phi(ratio) sqrt(pi / 2) = exp(-ratio^2 / 2) / 2.
    second = 0.5 * math.exp(-0.5 * ratio * ratio) * erfcx(max(far, 0.0) / (spread * _SQRT2))
    return min(max(first + second, 0.0), 1.0)


@jit(_BOUNDS_SIGNATURE)
def crossing_bounds(mean0, std0, walk, horizon, approach):
    """
    Return each condition's crossing bound, shape (K,).

    Parameters
    ----------
    mean0, std0, walk : numpy.ndarray
        ``y0``'s mean and std and the walk's variance per second, shape (K,) each.
    horizon : float
        ``tau`` [s].
    approach : numpy.ndarray
        The speed towards each line, ``>= 0``, shape (K,).

    Returns
    -------
    numpy.ndarray
        ``P(min over [0, tau] of y(t) < 0)`` bounded (:func:`_crossing_bound`), shape (K,).

    """
    bounds = mean0.copy()
    for index in range(mean0.size):
        bounds[index] = _crossing_bound(mean0[index], std0[index], walk[index], horizon,
                                        approach[index])
    return bounds


@jit(_SPEEDS_SIGNATURE)
def line_speeds(mean0, std0, walk, horizon, risks, low, high):
    """
    Return each condition's bound standing still and the largest speed towards it accepted.

    The bound rises with the speed towards the line. Where it stands still below the risk and
    the bracket ``[low, high]`` is not empty (``bound(low) <= risk <= bound(high)``, from the
    first term's thresholds), regula falsi with the Illinois rule narrows it for
    ``_FALSI_STEPS`` steps, from below: the answer is always a speed where the bound holds
    (``low`` at worst). The end kept twice in a row has its value halved, so that both ends
    move.

    Parameters
    ----------
    mean0, std0, walk : numpy.ndarray
        As :func:`crossing_bounds`, shape (K,) each.
    horizon : float
        ``tau`` [s].
    risks : numpy.ndarray
        The risk each condition is planned with, shape (K,).
    low, high : numpy.ndarray
        Speeds bracketing the answer, ``0 <= low``, shape (K,).

    Returns
    -------
    still, approach : numpy.ndarray
        The bound standing still, and the largest speed towards the line accepted (``-inf``
        where standing still is not: ``still >= risk``), shape (K,) each.

    """
    still = mean0.copy()
    approach = low.copy()
    for index in range(mean0.size):
        m0, s0, w, limit = mean0[index], std0[index], walk[index], risks[index]
        still[index] = _crossing_bound(m0, s0, w, horizon, 0.0)
        if not still[index] < limit:
            approach[index] = -math.inf
            continue
        lower, upper = low[index], high[index]
        if not upper > lower:
            continue
        below = _crossing_bound(m0, s0, w, horizon, lower) - limit
        above = _crossing_bound(m0, s0, w, horizon, upper) - limit
        last = 0
        for _ in range(_FALSI_STEPS):
            gap = above - below
            middle = upper - above * (upper - lower) / gap if gap > 0.0 else 0.5 * (lower
                                                                                     + upper)
            middle = min(max(middle, lower), upper)
            value = _crossing_bound(m0, s0, w, horizon, middle) - limit
            if value <= 0.0:
                below = value
                if last == 1:
                    above *= 0.5
                lower = middle
                last = 1
            else:
                if last == -1:
                    below *= 0.5
                above = value
                upper = middle
                last = -1
        approach[index] = lower
    return still, approach
