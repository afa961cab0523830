"""
Certified lower bounds on ``P(f >= 0)`` and ``P(g >= 0)`` for Gaussian ``z`` (docs/method.md, 13).

Cantelli's bound (section 5) holds for every distribution with the mean and variance of ``f``,
so it is loose for the one distribution the planner has: ``z = (r, w)`` Gaussian. This module
bounds the probability of the RVO condition ``f = (r x w)^2 - R^2 |w|^2 >= 0``, and of the
receding gate ``g = r . w >= 0``, from below for that Gaussian, by a proof whose only error is
floating-point rounding.

1. **Shift.** ``r x w`` is unchanged when ``r`` becomes ``r^ = r + T w`` with ``T = -lambda I``
   (``r . w`` with ``T = kappa J``, ``J`` the quarter turn). The ``lambda`` (``kappa``) that leaves
   the least cross-covariance ``D = Cov(r^, w) = S_rw + T S_ww``, measured by
   ``||D S_ww^-1/2||_F``, is ``tr(S_rw) / tr(S_ww)`` (``(S_rw[0, 1] - S_rw[1, 0]) / tr(S_ww)``).
   Isotropic blocks leave ``D = 0``.
2. **Independent part.** ``r^ = r' + K (w - mu_w)`` with the gain ``K = D S_ww^-1`` and ``r'``
   independent of ``w``: Gaussian with the mean of ``r^`` and the covariance
   ``S' = Cov(r^) - D S_ww^-1 D'``.
3. **Direction.** Write ``w = l d(theta)``, ``d`` the unit direction (``w = 0`` has probability
   0). Then ``f >= 0`` iff ``|r^ . n(theta)| >= R`` with ``n(theta) = (sin theta, -cos theta)`` the
   unit normal of ``w``, and ``g >= 0`` iff ``r^ . d(theta) >= 0``. Given ``w``, ``r^ . n`` is
   normal with variance ``s^2 = n' S' n`` and mean ``m = a(theta) + l b(theta)``,
   ``a = (mu^ - K mu_w) . n``, ``b = n' K d`` (for ``g``, ``d`` in place of ``n``). So
   ``P(f >= 0 | w) = F(m, s) = Phi((m - R) / s) + Phi((-m - R) / s)``, a folded normal.
4. **Cells.** The directions are cut into wedges, each with its opposite. Over a wedge and the
   lengths ``l`` of an event ``E`` of high probability, ``m`` and ``s^2`` lie in ranges bounded
   from the exact ranges of their sinusoids (``certificate_kernels.harmonic_range``), and ``F``
   is at least its value at the worst end of those ranges. Two kinds of ``E`` are tried, at
   several sizes ``rho``. The strip ``|e . (w - mu_w)| <= rho sd(e . w)``, ``e`` the mean's
   direction, bounds ``l`` on each wedge and misses with probability ``2 Phi(-rho)`` (the gain
   ``b = n' S_rw S_ww^-1 d`` does not depend on ``lambda``, as ``n . d = 0``). On the disc
   ``|S_ww^-1/2 (w - mu_w)| <= rho``, ``|n . K (w - mu_w)| <= rho ||D S_ww^-1/2||_2`` whatever
   the direction; it misses with probability ``exp(-rho^2 / 2)``. With no cross-covariance left
   (``D = 0``) ``m = a`` and the disc's largest size costs nothing. The largest of these bounds
   is kept; each is valid.
5. **Masses.** The probability that the direction falls in a wedge is at least the difference of
   the half-plane probabilities through its edges less its opposite's mass, and at least its
   width times the minimum of the direction's density (``certificate_kernels.cut_wedges``).
   With lower bounds ``q_k`` on the masses and ``F_k`` on the minima,
   ``P >= sum_k q_k F_k + (1 - sum_k q_k) min_k F_k - P(not E)``: the masses sum to one, and
   what no wedge claims gets the smallest minimum.

A quarter of the wedges are even over the circle, the others are spread within six standard
deviations of the mean direction of ``w`` (or evenly, when that direction is broad). For
``wedges`` a multiple of 8, doubling it refines the cut, which can only raise the bound; as
``wedges`` grows the bound tends to ``P`` itself when ``D = 0``, at first order in the width of the
wedges.

The horizon pair ``h1 = -(r . w) - tau |w|^2``, ``h2 = |r + tau w|^2 - R^2`` does not reduce to one
variable given the direction of ``w`` (``h1`` compares ``r . d`` with ``-tau l``, ``h2`` depends on
``r + tau w`` in the plane). With the receding gate on, the whole condition ``f or g or (h1 and
h2)`` holds wherever the segment from ``r`` to ``r + tau w`` misses the disc, and that event is
bounded from below by two normal tails per half-plane (:func:`horizon_certificate`).

The bounds are computed by numba (:mod:`prvo_planner.core.certificate_kernels`, loaded on the
first bound): steps 1 to 5, the exact cases, Cantelli's bound from the compiled moments of
:mod:`.moment_kernels`, the choice among the bounds and the horizon bound, each public function
of this module one compiled call after checking its arguments. Rounding is made to go the safe
way where it is cheap: the ranges of ``m`` and ``s^2`` are widened by a relative 1e-9 of their
scales, the density bound is shrunk by a relative 1e-9, and ``SLACK = 1e-9`` is subtracted from
every bound, which covers the error of ``Phi`` (the compiled one of :mod:`.special_kernels`,
below 2e-14 per call, checked against ``math.erfc`` and mpmath) summed over up to
``MAX_WEDGES`` wedges and the rounding of the sums. This holds for
covariances that are not ill conditioned; the bound is not computed in interval arithmetic.
"""

from dataclasses import dataclass
import math

import numpy as np

from .special import ndtri

DEFAULT_WEDGES = 64
MIN_WEDGES = 4
MAX_WEDGES = 4096
SLACK = 1e-9
# Sizes rho of the events: each gives a valid bound and the largest bound is kept. The disc of
# size 40 misses with probability exp(-800), which underflows to 0: with no cross-covariance
# left it is the one that counts.
STRIP_SIZES = (2.5, 3.5, 5.0)
DISC_SIZES = (3.0, 4.5, 40.0)
# Three quarters of the wedges are spread over the directions of w within this many standard
# deviations of the mean's (across it), where the mass is when w's direction is well defined.
ADAPTIVE_SPAN = 6.0
# S_ww with a smaller ratio of eigenvalues is not inverted: the density bound is skipped, and a
# cross-covariance left after the shift makes the wedge bound inapplicable (Cantelli's is used).
CONDITION_LIMIT = 1e-9
METHODS = ('deterministic', 'known-velocity', 'wedge', 'cantelli')
# The median k = E[f] / sd[f] at which the bound of 64 wedges first reaches eta, tracked beliefs
# (docs/method.md, section 13): where the planner in certified mode searches the rays.
SEARCH_ETAS = (0.8, 0.9, 0.95, 0.99)
SEARCH_MARGINS = (0.99, 1.26, 1.51, 1.89)
# Relative widening of the ranges of m and s^2, and shrinking of the density bound.
WIDENING = 1e-9
# Below this beta the direct form of psi(beta) cancels; its polynomial bound is used instead
# (:func:`prvo_planner.core.certificate_kernels.cut_wedges`).
PSI_SWITCH = -3.0
# Even directions of the half-planes :func:`horizon_certificate` tries, besides the means'.
HORIZON_DIRECTIONS = 64


@dataclass(frozen=True)
class Certificate:
    """
    Lower bounds on the probability of a condition, and which bound gave each.

    Attributes
    ----------
    probability : numpy.ndarray
        The bound, in [0, 1], shape (...).
    method : numpy.ndarray
        Per entry one of :data:`METHODS`, shape (...): ``'deterministic'`` (zero covariance:
        exactly 1 or 0 as the condition holds at the mean), ``'known-velocity'`` (``S_ww = 0``:
        the exact probability, less ``SLACK``), ``'wedge'`` (the bound of this module) or
        ``'cantelli'`` (Cantelli's ``k^2 / (1 + k^2)`` of ``k = E / sd``, less ``SLACK``, where
        it is at least the wedge bound, or where that does not apply: ``S_ww`` nearly singular
        with a cross-covariance left after the shift).

    """

    probability: np.ndarray
    method: np.ndarray


def search_margin(eta):
    """
    Return the margin ``k`` the rays are searched with to meet ``eta`` by the certified bound.

    Linear in ``eta`` between the measured edges (:data:`SEARCH_MARGINS`); outside them the
    measured ratio to Cantelli's ``k`` at the nearer end, which grows with Cantelli's (faster
    than the Gaussian's edge, so the searched velocities fall short less often). Never above
    Cantelli's ``k``. Only the search uses it: a velocity is kept only if certified.

    Parameters
    ----------
    eta : array_like
        Required probabilities, in (0, 1).

    Returns
    -------
    numpy.ndarray
        ``k`` per ``eta``.

    """
    eta = np.asarray(eta, dtype=float)
    cantelli = np.sqrt(eta / (1.0 - eta))
    low, high = (margin / math.sqrt(edge / (1.0 - edge)) for edge, margin in (
        (SEARCH_ETAS[0], SEARCH_MARGINS[0]), (SEARCH_ETAS[-1], SEARCH_MARGINS[-1])))
    margin = np.where(eta < SEARCH_ETAS[0], low * cantelli,
                      np.where(eta > SEARCH_ETAS[-1], high * cantelli,
                               np.interp(eta, SEARCH_ETAS, SEARCH_MARGINS)))
    return np.minimum(margin, cantelli)


def horizon_search_margin(eta):
    """
    Return the margin ``k'`` the horizon pair is searched with to meet ``eta`` by a certificate.

    :func:`horizon_certificate` spends ``1 - eta`` on two normal tails, of ``e . r`` and of
    ``e . p``, ``p = r + tau w``; the first is negligible whenever the robots are apart now, so
    the far end needs ``(e . mu_p - R) / s_p >= Phi^-1(eta)``. ``h2``'s ``mean / sd`` is about
    ``(|p| - R) / s_p (|p| + R) / (2 |p|)``, at most ``(|p| - R) / s_p``: searched with
    ``Phi^-1(eta)`` it accepts only where that end meets ``eta``. Clipped to ``[0, k']`` with
    Cantelli's ``k' = sqrt((1 + eta) / (1 - eta))``. Only the search uses it: a velocity is kept
    only if certified.

    Parameters
    ----------
    eta : array_like
        Required probabilities, in (0, 1).

    Returns
    -------
    numpy.ndarray
        ``k'`` per ``eta``.

    """
    eta = np.asarray(eta, dtype=float)
    return np.clip(ndtri(eta), 0.0, np.sqrt((1.0 + eta) / (1.0 - eta)))


def _validated(mean, cov, wedges):
    """Check the arguments; return ``mean`` (N, 4), ``cov`` (N, 4, 4) and the batch shape."""
    mean = np.asarray(mean, dtype=float)
    cov = np.asarray(cov, dtype=float)
    if mean.shape[-1:] != (4,) or cov.shape[-2:] != (4, 4):
        raise ValueError(f'mean must have shape (..., 4) and cov (..., 4, 4), got '
                         f'{mean.shape} and {cov.shape}')
    _check_wedges(wedges)
    shape = np.broadcast_shapes(mean.shape[:-1], cov.shape[:-2])
    return (np.ascontiguousarray(np.broadcast_to(mean, shape + (4,)).reshape(-1, 4)),
            np.ascontiguousarray(np.broadcast_to(cov, shape + (4, 4)).reshape(-1, 4, 4)), shape)


def _check_wedges(wedges):
    """Raise ValueError unless WEDGES is an even integer in [MIN_WEDGES, MAX_WEDGES]."""
    if (isinstance(wedges, bool) or not isinstance(wedges, (int, np.integer))
            or not MIN_WEDGES <= wedges <= MAX_WEDGES or wedges % 2):
        raise ValueError(f'wedges must be an even integer in [{MIN_WEDGES}, {MAX_WEDGES}], '
                         f'got {wedges!r}')


def _certificate(mean, cov, radius, across, wedges, shape):
    """Return the :class:`Certificate` of ``f`` (ACROSS) or of ``g`` (compiled)."""
    # Imported, and so loaded or compiled, on the first bound: a process that certifies
    # nothing does not import numba for it.
    from .certificate_kernels import condition_bounds

    count = mean.shape[0]
    probability, method = condition_bounds(mean, cov, radius, np.ones(count),
                                           np.full(count, not across), math.inf, wedges // 2,
                                           across)
    return Certificate(probability=probability.reshape(shape),
                       method=np.array(METHODS)[method].reshape(shape))


def rvo_certificate(mean, cov, radius, wedges=DEFAULT_WEDGES):
    """
    Certified lower bound on ``P(f >= 0)``, ``f = (r x w)^2 - R^2 |w|^2``, for Gaussian ``z``.

    The same ``z``, ``f`` and conventions as :func:`prvo_planner.core.moments.rvo_moments`:
    ``z = (r_x, r_y, w_x, w_y)`` with ``w`` the relative velocity at the pair's shares (``u`` of
    RVO at the share 1/2); at a command ``v_c`` its mean is ``Encounter.origin`` plus
    ``Encounter.lead v_c`` in the velocity components, its covariance ``Encounter.cov``.
    Batched over leading axes, so that many (neighbour, velocity) pairs are certified in one
    call. The module docstring gives the bound and its proof.

    Parameters
    ----------
    mean : array_like
        Mean of ``z``, shape (..., 4).
    cov : array_like
        Covariance of ``z``, shape (..., 4, 4), symmetric PSD.
    radius : float or array_like
        ``R``, broadcastable to the batch shape.
    wedges : int
        Wedges of the circle of directions (in opposite pairs), even, in [4, 4096]; more are
        tighter and cost proportionally (64: within about 0.003 of ``P`` at Cantelli's ``k = 2``
        edge, 0.05 at ``k = 1``; see docs/method.md, section 13).

    Returns
    -------
    Certificate
        ``probability`` and ``method``, of the batch shape.

    """
    mean, cov, shape = _validated(mean, cov, wedges)
    radius = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=float),
                                                  shape).reshape(-1))
    return _certificate(mean, cov, radius, True, wedges, shape)


def receding_certificate(mean, cov, wedges=DEFAULT_WEDGES):
    """
    Certified lower bound on ``P(g >= 0)``, ``g = r . w`` (the receding gate), for Gaussian ``z``.

    As :func:`rvo_certificate`, with ``T = kappa J`` (``(J w) . w = 0``) and the half-normal
    ``P(r^ . d >= 0 | w)`` of the direction ``d`` itself: ``g`` changes sign with ``w``, so a
    wedge and its opposite have different minima.

    Parameters
    ----------
    mean, cov, wedges
        As for :func:`rvo_certificate`.

    Returns
    -------
    Certificate
        ``probability`` and ``method``, of the batch shape.

    """
    mean, cov, shape = _validated(mean, cov, wedges)
    return _certificate(mean, cov, np.zeros(mean.shape[0]), False, wedges, shape)


def condition_bound(mean, cov, radius, required, gated, horizon=None, wedges=DEFAULT_WEDGES):
    """
    Certified lower bound on the accepted condition's probability, computed as far as needed.

    The planner's bound on ``P(f >= 0 or g >= 0 or (h1 >= 0 and h2 >= 0))`` for a neighbour: the
    bound of :func:`rvo_certificate` on ``P(f >= 0)``; where that falls short of ``required``
    and the gate counts (``gated``), the larger with :func:`receding_certificate`'s on
    ``P(g >= 0)``; and where that too falls short and the horizon is finite, the larger with
    :func:`horizon_certificate`'s on the whole condition. Each is a lower bound on the
    condition's probability, so the largest is one. A later bound is computed only for the
    entries the earlier ones leave short (each entry's bound is its own, whatever else is
    bounded with it).
    The wedges and their masses depend on ``w`` alone: ``f`` and ``g`` share them, and the
    moments of both, Cantelli's floors, come from one compiled call.

    Parameters
    ----------
    mean : array_like
        Mean of ``z``, shape (N, 4) (no other batch shapes: one compiled call, no broadcasting).
    cov : array_like
        Covariance of ``z``, shape (N, 4, 4), symmetric PSD.
    radius : array_like
        ``R``, shape (N,).
    required : array_like
        The probability each entry should be certified for, shape (N,).
    gated : array_like
        Whether the gate counts for each entry (bool), shape (N,).
    horizon : float or None
        The time horizon ``tau`` [s]; None: infinite (no horizon pair).
    wedges : int
        As for :func:`rvo_certificate`.

    Returns
    -------
    numpy.ndarray
        The bound, in [0, 1], shape (N,).

    """
    from .certificate_kernels import condition_bounds

    return condition_bounds(*_condition_arguments(mean, cov, radius, required, gated, horizon,
                                                  wedges), True)[0]


def condition_bound_until_short(mean, cov, radius, required, gated, horizon=None,
                                wedges=DEFAULT_WEDGES):
    """
    :func:`condition_bound` of the entries in order, up to the first short of ``required``.

    Whether a velocity is certified against every neighbour is settled by its first neighbour
    short (``_anchored`` of the planner: its neighbours likeliest short first); an entry's bound
    does not depend on the others bounded with it, so each computed is :func:`condition_bound`'s.
    The arguments as :func:`condition_bound`'s.

    Returns
    -------
    bounds : numpy.ndarray
        The bound per entry, shape (N,): the first ``done`` computed, 0 after.
    done : int
        How many were bounded: N, or up to and with the first short one.

    """
    from .certificate_kernels import bounds_until_short

    return bounds_until_short(*_condition_arguments(mean, cov, radius, required, gated, horizon,
                                                    wedges))


def _condition_arguments(mean, cov, radius, required, gated, horizon, wedges):
    """Check WEDGES; return the compiled condition bound's arguments (contiguous, typed)."""
    _check_wedges(wedges)
    return (np.ascontiguousarray(mean, dtype=np.float64),
            np.ascontiguousarray(cov, dtype=np.float64),
            np.ascontiguousarray(radius, dtype=np.float64),
            np.ascontiguousarray(required, dtype=np.float64),
            np.ascontiguousarray(gated, dtype=bool),
            math.inf if horizon is None else float(horizon), wedges // 2)


def horizon_certificate(mean, cov, radius, horizon):
    """
    Certified lower bound on ``P(f >= 0 or g >= 0 or (h1 >= 0 and h2 >= 0))`` for Gaussian ``z``.

    The accepted condition with the receding gate on. ``z``, ``f`` and ``g`` as in
    :func:`rvo_certificate` and :func:`receding_certificate`; ``h1 = -(r . w) - tau |w|^2`` and
    ``h2 = |r + tau w|^2 - R^2`` with ``tau`` the time horizon. The event ``E`` that the segment
    ``r + t w``, ``t`` in ``[0, tau]``, misses the open disc of radius ``R`` lies within the
    condition: with ``t* = -(r . w) / |w|^2`` the time of closest approach, ``t* <= 0`` is
    ``g >= 0``; for ``t*`` in ``(0, tau]`` the closest distance ``|r x w| / |w| >= R`` is
    ``f >= 0``; for ``t* > tau`` both ``h1 = |w|^2 (t* - tau) > 0`` and ``h2 >= 0`` hold. ``E``
    holds when both ends of the segment lie in a half-plane ``e . x >= R``, ``e`` a unit vector
    (the segment is convex; a segment that misses the disc has such an ``e``, by separation),
    so for every fixed ``e``

        ``P >= 1 - Phi((R - e . mu_r) / s_r) - Phi((R - e . mu_p) / s_p)``

    with ``p = r + tau w`` and ``s`` the standard deviations of ``e . r`` and ``e . p``, exact
    normals. The largest bound over ``HORIZON_DIRECTIONS`` even directions and those of
    ``mu_r``, ``mu_p`` and their bisector is returned, less ``SLACK``. Unlike the pair's
    Cantelli bound it needs no gate-free form: it bounds the condition only where the gate
    counts.

    Parameters
    ----------
    mean : array_like
        Mean of ``z``, shape (..., 4).
    cov : array_like
        Covariance of ``z``, shape (..., 4, 4), symmetric PSD.
    radius : float or array_like
        ``R``, broadcastable to the batch shape.
    horizon : float or array_like
        ``tau`` [s], > 0 and finite, broadcastable to the batch shape.

    Returns
    -------
    numpy.ndarray
        The bound, in [0, 1], of the batch shape.

    """
    mean, cov, shape = _validated(mean, cov, DEFAULT_WEDGES)
    radius, horizon = (np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float),
                                                            shape).reshape(-1))
                       for value in (radius, horizon))
    from .certificate_kernels import horizon_bounds

    return horizon_bounds(mean, cov, radius, horizon).reshape(shape)
