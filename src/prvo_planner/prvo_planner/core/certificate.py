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
   from the exact ranges of their sinusoids (:func:`harmonic_ranges`), and ``F`` is at least its
   value at the worst end (:func:`folded_normal_minima`). Two kinds of ``E`` are tried, at
   several sizes ``rho``. The strip ``|e . (w - mu_w)| <= rho sd(e . w)``, ``e`` the mean's
   direction, bounds ``l`` on each wedge and misses with probability ``2 Phi(-rho)`` (the gain
   ``b = n' S_rw S_ww^-1 d`` does not depend on ``lambda``, as ``n . d = 0``). On the disc
   ``|S_ww^-1/2 (w - mu_w)| <= rho``, ``|n . K (w - mu_w)| <= rho ||D S_ww^-1/2||_2`` whatever
   the direction; it misses with probability ``exp(-rho^2 / 2)``. With no cross-covariance left
   (``D = 0``) ``m = a`` and the disc's largest size costs nothing. The largest of these bounds
   is kept; each is valid.
5. **Masses.** The probability that the direction falls in a wedge is at least the difference of
   the half-plane probabilities through its edges less its opposite's mass, and at least its
   width times the minimum of the direction's density (:func:`wedge_masses`). With lower bounds
   ``q_k`` on the masses and ``F_k`` on the minima, ``P >= sum_k q_k F_k + (1 - sum_k q_k) min_k
   F_k - P(not E)``: the masses sum to one, and what no wedge claims gets the smallest minimum.

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

Rounding is made to go the safe way where it is cheap: the ranges of ``m`` and ``s^2`` are
widened by a relative 1e-9 of their scales, the density bound is shrunk by a relative 1e-9, and
``SLACK = 1e-9`` is subtracted from every bound, which covers the error of ``Phi`` (scipy's
``ndtr``, below 2e-14 per call, checked against ``math.erfc``) summed over up to ``MAX_WEDGES``
wedges and the rounding of the sums. This holds for covariances that are not ill conditioned; the
bound is not computed in interval arithmetic.
"""

from dataclasses import dataclass
import math

import numpy as np

from .moments import rvo_moments
from .special import ndtr, ndtri

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
_WIDENING = 1e-9

_SQRT_HALF = math.sqrt(0.5)
_SQRT_2PI = math.sqrt(2.0 * math.pi)
# Below this beta the direct form of psi(beta) cancels; its polynomial bound is used instead.
_PSI_SWITCH = -3.0
_QUARTER_TURN = np.array([[0.0, -1.0], [1.0, 0.0]])
_ADJUGATE_SIGNS = np.array([[1.0, -1.0], [-1.0, 1.0]])
# g = z' G z with G = [[0, I], [I, 0]] / 2.
_HALF_SWAP = np.block([[np.zeros((2, 2)), 0.5 * np.eye(2)], [0.5 * np.eye(2), np.zeros((2, 2))]])
# Even directions of the half-planes :func:`horizon_certificate` tries, besides the means'.
HORIZON_DIRECTIONS = 64
_HORIZON_ANGLES = 2.0 * math.pi * np.arange(HORIZON_DIRECTIONS) / HORIZON_DIRECTIONS


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


# The strip events' miss probabilities 2 Phi(-rho) = erfc(rho / sqrt(2)), and the discs'
# exp(-rho^2 / 2).
_STRIP_MISSES = np.array([math.erfc(size * _SQRT_HALF) for size in STRIP_SIZES])
_DISC_MISSES = np.exp(-0.5 * np.square(DISC_SIZES))


def _ratio(numerator, denominator, zero_by_zero):
    """``numerator / denominator`` for ``denominator >= 0``: ``+-inf`` by 0, ``0 / 0`` given."""
    with np.errstate(divide='ignore', invalid='ignore'):
        quotient = numerator / denominator
    return np.where(np.isnan(quotient), zero_by_zero, quotient)


def _linear_coefficients(vector, across):
    """
    ``vector . v(x)`` as ``c cos x + s sin x``: the coefficients ``(c, s)``, shape (N, 2).

    ``v`` is the normal ``n(x)`` (``across``) or the direction ``d(x)``; ``vector`` (N, 2).
    """
    # vector . n(x) = vector_x sin x - vector_y cos x.
    return vector[:, ::-1] * np.array([-1.0, 1.0]) if across else vector


def _quadratic_coefficients(matrix, across):
    """
    ``v' M v`` as ``constant + c cos 2x + s sin 2x``: ``constant`` (N,) and ``(c, s)`` (N, 2).

    ``d' M d = (Mxx + Myy) / 2 + (Mxx - Myy) / 2 cos 2x + Mxy sin 2x``; ``n(x) = d(x - pi / 2)``
    (``across``) flips the sign of the sinusoid. ``M`` is symmetric, shape (N, 2, 2).
    """
    sign = -1.0 if across else 1.0
    return (0.5 * (matrix[:, 0, 0] + matrix[:, 1, 1]),
            sign * np.stack([0.5 * (matrix[:, 0, 0] - matrix[:, 1, 1]), matrix[:, 0, 1]], axis=1))


def _gain_coefficients(gain, across):
    """
    ``b(x) = v' K d`` as ``constant + c cos 2x + s sin 2x``, ``v`` = ``n`` (``across``) or ``d``.

    ``d' K d = (K00 + K11) / 2 + (K00 - K11) / 2 cos 2x + (K01 + K10) / 2 sin 2x`` and
    ``n' K d = (K01 - K10) / 2 - (K01 + K10) / 2 cos 2x + (K00 - K11) / 2 sin 2x``; both are the
    same on a wedge and its opposite. ``K`` has shape (N, 2, 2); returns (N,) and (N, 2).
    """
    difference_half = 0.5 * (gain[:, 0, 0] - gain[:, 1, 1])
    sum_half = 0.5 * (gain[:, 0, 1] + gain[:, 1, 0])
    if across:
        return (0.5 * (gain[:, 0, 1] - gain[:, 1, 0]),
                np.stack([-sum_half, difference_half], axis=1))
    return 0.5 * (gain[:, 0, 0] + gain[:, 1, 1]), np.stack([difference_half, sum_half], axis=1)


def harmonic_ranges(start, width, single, double):
    """
    Exact ranges of sinusoids ``c cos mx + s sin mx`` of the angle ``x`` over wedges, ``m`` 1 or 2.

    With ``y = m x`` over ``[m a, m a + m w]`` (``m w <= 2 pi``), the extremes of
    ``c cos y + s sin y`` are at the ends or at the interior stationary points: the peak
    ``atan2(s, c)``, of value ``hypot(c, s)``, and the trough half a turn from it. A bound needs
    several sinusoids over the same wedges: they are computed in one pass (a range costs about
    twenty numpy calls, mostly per call), and the ends' cosines and sines once per ``m`` (they
    cost per element).

    Parameters
    ----------
    start, width : numpy.ndarray
        The wedges ``[a, a + w]``, shape (N, K), ``0 <= w <= pi``.
    single : list of numpy.ndarray
        S coefficients ``(c, s)`` with ``m = 1``, each (N, 2).
    double : list of numpy.ndarray
        D coefficients ``(c, s)`` with ``m = 2``, each (N, 2).

    Returns
    -------
    low, high : numpy.ndarray
        The minimum and maximum, shape (S + D, N, K): the single-angle sinusoids, then the
        double-angle ones.

    """
    coefficients = np.stack(single + double)[..., None]
    cosine, sine = coefficients[:, :, 0], coefficients[:, :, 1]
    multiple = np.repeat([0, 1], [len(single), len(double)])
    begin = np.array([1.0, 2.0])[:, None, None] * start
    span = np.array([1.0, 2.0])[:, None, None] * width
    ends = np.stack([begin, begin + span])
    # (2, S + D, N, K): each sinusoid's value at the wedge's first and last edge.
    values = cosine * np.cos(ends)[:, multiple] + sine * np.sin(ends)[:, multiple]
    amplitude = np.hypot(cosine, sine)
    peak = np.arctan2(sine, cosine)
    begin, span = begin[multiple], span[multiple]
    inside_peak = np.mod(peak - begin, 2.0 * np.pi) <= span
    inside_trough = np.mod(peak + np.pi - begin, 2.0 * np.pi) <= span
    return (np.where(inside_trough, -amplitude, values.min(axis=0)),
            np.where(inside_peak, amplitude, values.max(axis=0)))


def _wedge_edges(mu_w, cov_ww, pairs):
    """
    Cut the line directions ``[0, pi)`` of ``w`` into ``pairs`` wedges (each with its opposite).

    A quarter of the edges are even over the half turn. The others resolve where the mass is: a
    narrow direction (``|mu_w| > 2 sigma``) gets the directions of ``mu_w + z sigma e``, ``e``
    across ``mu_w``, ``sigma`` the standard deviation of ``w`` along ``e``, for ``z`` even in
    ``[-6, 6)``; a broad one gets more even edges. Every set is nested when ``pairs`` doubles, so
    the cut is refined.

    Parameters
    ----------
    mu_w : numpy.ndarray
        Shape (N, 2).
    cov_ww : numpy.ndarray
        Shape (N, 2, 2).
    pairs : int
        Number of wedges of the half turn, >= 2.

    Returns
    -------
    start, width : numpy.ndarray
        Each wedge's first edge in ``[0, pi)`` and its width, shape (N, pairs), the widths
        summing to ``pi`` (wedges of zero width are possible).

    """
    even = max(pairs // 4, 1)
    spread = pairs - even
    # sigma |mu_w| without dividing by |mu_w|: (-mu_y, mu_x)' S_ww (-mu_y, mu_x).
    across = np.sqrt(np.maximum(mu_w[:, 1] ** 2 * cov_ww[:, 0, 0]
                                - 2.0 * mu_w[:, 0] * mu_w[:, 1] * cov_ww[:, 0, 1]
                                + mu_w[:, 0] ** 2 * cov_ww[:, 1, 1], 0.0))
    speed_sq = np.sum(mu_w * mu_w, axis=1)
    steps = ADAPTIVE_SPAN * (2.0 * np.arange(spread) / spread - 1.0)
    narrow = np.arctan2(mu_w[:, 1], mu_w[:, 0])[:, None] + np.arctan2(
        across[:, None] * steps, speed_sq[:, None])
    broad = np.pi * np.arange(spread) / spread
    adaptive = np.where((speed_sq > 2.0 * across)[:, None], np.mod(narrow, np.pi), broad)
    edges = np.sort(np.concatenate([np.broadcast_to(np.pi * np.arange(even) / even,
                                                    (mu_w.shape[0], even)), adaptive], axis=1),
                    axis=1)
    # mod can round up to pi itself.
    edges = np.minimum(edges, np.nextafter(np.pi, 0.0))
    return edges, np.diff(edges, axis=1, append=edges[:, :1] + np.pi)


def _adjugate(matrix):
    """
    Return ``[[d, -b], [-b, a]]`` of each ``[[a, b], [., d]]`` (N, 2, 2), det times the inverse.

    Read from the upper triangle, as a symmetric matrix's; one gather instead of four stacks.
    """
    return matrix.reshape(-1, 4)[:, [3, 1, 1, 0]].reshape(-1, 2, 2) * _ADJUGATE_SIGNS


def _half_plane_arguments(mu_w, cov_ww, angle):
    """
    ``x`` with ``Phi(x) = P(d(angle) x w > 0)``, that ``w`` points into ``(angle, angle + pi)``.

    ``d x w`` is normal with mean ``d x mu_w`` and variance ``n' S_ww n``; with zero variance the
    probability is 1 if the mean is positive, else 0 (the inequality is strict). Shapes: ``mu_w``
    (N, 2), ``cov_ww`` (N, 2, 2), ``angle`` (N, K); result (N, K).
    """
    cos, sin = np.cos(angle), np.sin(angle)
    mean = cos * mu_w[:, 1, None] - sin * mu_w[:, 0, None]
    variance = (cov_ww[:, 0, 0, None] * sin * sin - 2.0 * cov_ww[:, 0, 1, None] * sin * cos
                + cov_ww[:, 1, 1, None] * cos * cos)
    return _ratio(mean, np.sqrt(np.maximum(variance, 0.0)), -np.inf)


def _scaled_psi_lower(beta, cdf, quadratic):
    """
    Lower bound on ``exp(-C/2) psi(beta)``, ``psi(beta) = int_0^inf y exp(-y^2/2 + beta y) dy``.

    ``psi(beta) = 1 + sqrt(2 pi) beta exp(beta^2 / 2) Phi(beta)``, increasing in ``beta``. Below
    ``beta = -3`` that form cancels; there ``exp(-y^2/2) >= 1 - y^2/2`` gives
    ``psi(beta) >= 1/beta^2 - 3/beta^4``. ``cdf`` is ``Phi(max(beta, -3))``; ``beta``, ``cdf`` and
    ``C`` broadcast; the bound is >= 0.
    """
    scale = np.exp(-0.5 * quadratic)
    direct_beta = np.maximum(beta, _PSI_SWITCH)
    direct = scale + _SQRT_2PI * direct_beta * cdf * np.exp(
        0.5 * (direct_beta * direct_beta - quadratic))
    inverse_sq = 1.0 / np.maximum(beta * beta, _PSI_SWITCH ** 2)
    asymptotic = scale * inverse_sq * (1.0 - 3.0 * inverse_sq)
    return np.maximum(np.where(beta >= _PSI_SWITCH, direct, asymptotic), 0.0)


def wedge_masses(mu_w, cov_ww, start, width, invertible):
    """
    Lower bounds on the probabilities that the direction of ``w`` falls in each wedge.

    Let ``m`` and ``m~`` be the masses of the wedge ``W`` and of its opposite ``W + pi``.

    * ``m - m~`` is exactly the difference of the half-plane probabilities through the wedge's
      edges, ``P(theta in (a, a + pi)) - P(theta in (b, b + pi))``.
    * ``m >= width * min_W p``, with the density of the direction of ``w ~ N(mu, S)``
      ``p(x) = exp(-C/2) psi(B / sqrt(A)) / (2 pi sqrt(det S) A)``, ``A = d' S^-1 d``,
      ``B = d' S^-1 mu``, ``C = mu' S^-1 mu`` (the density integrated along the ray ``l d``);
      ``psi`` increases, so the minimum is bounded from the exact ranges of the sinusoids ``A``
      and ``B``. Used only where ``S`` may be inverted (else 0).

    So ``m >= max(L, (m - m~) + L~)`` and ``m~ >= max(L~, L - (m - m~))`` with the density bounds
    ``L``, ``L~``.

    Parameters
    ----------
    mu_w : numpy.ndarray
        Shape (N, 2).
    cov_ww : numpy.ndarray
        Shape (N, 2, 2).
    start, width : numpy.ndarray
        Wedges of the half turn, shape (N, K), widths <= pi.
    invertible : numpy.ndarray
        Whether ``S_ww`` may be inverted, shape (N,).

    Returns
    -------
    numpy.ndarray
        Lower bounds on the masses of the wedges and then of their opposites, shape (N, 2 K).

    """
    edges = np.concatenate([start, start[:, -1:] + width[:, -1:]], axis=1)
    # The density of a singular S_ww is not used: the identity stands in, so that every value
    # stays finite.
    density_cov = np.where(invertible[:, None, None], cov_ww, np.eye(2))
    determinant = density_cov[:, 0, 0] * density_cov[:, 1, 1] - density_cov[:, 0, 1] ** 2
    precision = _adjugate(density_cov) / determinant[:, None, None]
    pulled = np.einsum('nij,nj->ni', precision, mu_w)
    quadratic = np.einsum('ni,ni->n', pulled, mu_w)[:, None]
    constant, coefficients = _quadratic_coefficients(precision, across=False)
    (b_low, a_low), (b_high, a_high) = harmonic_ranges(start, width, [pulled], [coefficients])
    a_low, a_high = constant[:, None] + a_low, constant[:, None] + a_high
    # A = d' S^-1 d >= 1 / lambda_max(S) > 0; the floor keeps rounding from reaching 0.
    a_low = np.sqrt(np.maximum(a_low, 0.5 / (density_cov[:, 0, 0] + density_cov[:, 1, 1])[
        :, None]))
    # The smallest B / sqrt(A) over the wedge (and its opposite, where B changes sign): a
    # positive B over the largest A, a negative one over the smallest.
    low_b = np.stack([b_low, -b_high])
    beta = np.where(low_b >= 0.0, low_b / np.sqrt(a_high), low_b / a_low)
    # One call of ndtr for the half planes and the densities: its cost is mostly per call.
    arguments = _half_plane_arguments(mu_w, cov_ww, edges)
    cdf = ndtr(np.concatenate([arguments.ravel(), np.maximum(beta, _PSI_SWITCH).ravel()]))
    half_planes = cdf[:arguments.size].reshape(arguments.shape)
    difference = half_planes[:, :-1] - half_planes[:, 1:]
    scale = ((1.0 - _WIDENING) / (2.0 * np.pi * np.sqrt(determinant)))[:, None] * width
    own, opposite = np.where(invertible[:, None], scale * _scaled_psi_lower(
        beta, cdf[arguments.size:].reshape(beta.shape), quadratic) / a_high, 0.0)
    return np.concatenate([np.maximum(own, difference + opposite),
                           np.maximum(opposite, own - difference)], axis=1)


@dataclass(frozen=True)
class _Wedges:
    """
    Each entry's wedges of the directions of ``w``, and lower bounds on their masses.

    They depend on the mean and covariance of ``w`` alone: the bounds on ``f`` and on ``g`` of
    the same entries share them (:func:`condition_bound`).

    Attributes
    ----------
    start, width : numpy.ndarray
        The wedges of the half turn, shape (N, K) (:func:`_wedge_edges`).
    masses : numpy.ndarray
        Lower bounds on the masses of the wedges, then of their opposites, shape (N, 2 K)
        (:func:`wedge_masses`).
    invertible : numpy.ndarray
        Whether ``S_ww`` may be inverted, shape (N,).

    """

    start: np.ndarray
    width: np.ndarray
    masses: np.ndarray
    invertible: np.ndarray

    def take(self, rows):
        """Return the wedges of the entries ROWS (a mask or indices)."""
        return _Wedges(start=self.start[rows], width=self.width[rows],
                       masses=self.masses[rows], invertible=self.invertible[rows])


def _invertible(cov_ww):
    """Whether each ``S_ww`` (N, 2, 2) may be inverted: eigenvalue ratio >= ``CONDITION_LIMIT``."""
    trace = cov_ww[:, 0, 0] + cov_ww[:, 1, 1]
    determinant = cov_ww[:, 0, 0] * cov_ww[:, 1, 1] - cov_ww[:, 0, 1] ** 2
    # From det / tr^2 = ratio / (1 + ratio)^2.
    return determinant > CONDITION_LIMIT / (1.0 + CONDITION_LIMIT) ** 2 * trace * trace


def _wedges(mean, cov, wedges):
    """Return the :class:`_Wedges` of ``wedges`` wedges of ``mean`` (N, 4), ``cov`` (N, 4, 4)."""
    mu_w, cov_ww = mean[:, 2:], cov[:, 2:, 2:]
    invertible = _invertible(cov_ww)
    start, width = _wedge_edges(mu_w, cov_ww, wedges // 2)
    return _Wedges(start=start, width=width,
                   masses=wedge_masses(mu_w, cov_ww, start, width, invertible),
                   invertible=invertible)


@dataclass(frozen=True)
class _Split:
    """
    ``r^ = r + T w`` split into ``r'``, independent of ``w``, and ``K (w - mu_w)``.

    Attributes
    ----------
    mean : numpy.ndarray
        Mean of ``r'`` and ``r^``, shape (N, 2).
    cov : numpy.ndarray
        ``S' = Cov(r^) - D S_ww^-1 D'``, shape (N, 2, 2).
    gain : numpy.ndarray
        ``K = D S_ww^-1``, shape (N, 2, 2) (0 where ``D = 0`` or ``S_ww`` is not inverted).
    reach : numpy.ndarray
        ``||D S_ww^-1/2||_2``, shape (N,).
    scale_sq : numpy.ndarray
        The scale of the entries of ``S'``, for widening its ranges, shape (N,).
    usable : numpy.ndarray
        False where ``S_ww`` is not inverted but ``D != 0``: the split is unknown, shape (N,).
    invertible : numpy.ndarray
        Whether ``S_ww`` may be inverted, shape (N,).

    """

    mean: np.ndarray
    cov: np.ndarray
    gain: np.ndarray
    reach: np.ndarray
    scale_sq: np.ndarray
    usable: np.ndarray
    invertible: np.ndarray


def _split(mean, cov, shift, invertible):
    """Return the :class:`_Split` of ``r^ = r + T w``; ``mean`` (N, 4), ``cov``, ``T``, (N,)."""
    mu_r, mu_w = mean[:, :2], mean[:, 2:]
    cov_rr, cov_rw, cov_ww = cov[:, :2, :2], cov[:, :2, 2:], cov[:, 2:, 2:]
    shift_t = shift.swapaxes(1, 2)
    cross = cov_rw + shift @ cov_ww
    cov_hat = cov_rr + cov_rw @ shift_t + shift @ cov_rw.swapaxes(1, 2) + shift @ cov_ww @ shift_t
    determinant = cov_ww[:, 0, 0] * cov_ww[:, 1, 1] - cov_ww[:, 0, 1] ** 2
    no_cross = ~cross.any(axis=(1, 2))
    inverse = _adjugate(cov_ww) / np.where(invertible, determinant, 1.0)[:, None, None]
    gain = np.where((invertible & ~no_cross)[:, None, None], cross @ inverse, 0.0)
    explained = gain @ cross.swapaxes(1, 2)
    explained = 0.5 * (explained + explained.swapaxes(1, 2))
    half_trace = 0.5 * (explained[:, 0, 0] + explained[:, 1, 1])
    spread = np.hypot(0.5 * (explained[:, 0, 0] - explained[:, 1, 1]), explained[:, 0, 1])
    # The largest eigenvalue of D S^-1 D', grown by the relative error of the inverse.
    reach = np.sqrt(np.maximum(half_trace + spread, 0.0)) * (1.0 + 1e-6)
    scale_sq = (np.abs(cov_rr).sum(axis=(1, 2)) + 2.0 * np.abs(cov_rw @ shift_t).sum(axis=(1, 2))
                + np.abs(shift @ cov_ww @ shift_t).sum(axis=(1, 2))
                + np.abs(explained).sum(axis=(1, 2)))
    return _Split(mean=mu_r + np.einsum('nij,nj->ni', shift, mu_w), cov=cov_hat - explained,
                  gain=gain, reach=reach, scale_sq=scale_sq, usable=invertible | no_cross,
                  invertible=invertible)


def _interval_product(low, high, factor_low, factor_high):
    """Range of ``x y`` for ``x`` in ``[low, high]``, ``y`` in a range (``0 inf`` taken as 0)."""
    with np.errstate(invalid='ignore'):
        corners = np.stack([low * factor_low, low * factor_high, high * factor_low,
                            high * factor_high])
    corners = np.where(np.isnan(corners), 0.0, corners)
    return corners.min(axis=0), corners.max(axis=0)


def _strip_lengths(c_low, c_high, t_low, t_high):
    """
    Range of the length ``l`` of ``w = l d`` on a wedge where ``c = e . d`` is in a range.

    On the strip ``e . w`` in ``[t_low, t_high]``, ``l = (e . w) / c``: bounded where ``c`` keeps
    its sign over the wedge, ``[0, inf)`` where it may vanish.

    Parameters
    ----------
    c_low, c_high : numpy.ndarray
        Range of ``c`` per wedge, shape (N, K, 1).
    t_low, t_high : numpy.ndarray
        The strip per event, shape (N, 1, J).

    Returns
    -------
    low, high : numpy.ndarray
        Shape (N, K, J); ``low > high`` where the strip misses the wedge.

    """
    facing, away = c_low > 0.0, c_high < 0.0
    # Denominators of 1 where unused keep the divisions finite.
    front_low = np.maximum(t_low, 0.0) / np.where(facing, c_high, 1.0)
    front_high = t_high / np.where(facing, c_low, 1.0)
    back_low = np.maximum(-t_high, 0.0) / np.where(away, -c_low, 1.0)
    back_high = -t_low / np.where(away, -c_high, 1.0)
    low = np.where(facing, front_low, np.where(away, back_low, 0.0))
    high = np.where(facing, front_high, np.where(away, back_high, np.inf))
    missed = facing & (t_high < 0.0) | away & (t_low > 0.0)
    return np.where(missed, np.inf, low), np.where(missed, -np.inf, high)


def _ranges(split, mu_w, cov_ww, wedges, across):
    """
    Ranges of the conditional mean ``m`` and variance ``s^2`` of ``r^ . v`` on every wedge.

    ``v`` is ``n`` for ``f`` (``across``) and ``d`` for ``g``; ``s^2 = v' S' v``. On the disc of
    size ``rho``, ``m`` is within ``rho ||D S_ww^-1/2||`` of ``mu^ . v``; on the strip,
    ``m = a + l b`` with the ranges of ``a = (mu^ - K mu_w) . v``, of ``b = v' K d`` and of ``l``
    (:func:`_strip_lengths`). On the opposite wedge ``v`` and ``d`` change sign: ``mu^ . v`` and
    ``a`` do, ``b`` and ``s^2`` do not. The strips are tried only where some entry has a
    cross-covariance left (``reach > 0``). Every sinusoid's range comes from one call
    (:func:`harmonic_ranges`).

    Parameters
    ----------
    split : _Split
        The shifted position and its gain.
    mu_w : numpy.ndarray
        Shape (N, 2).
    cov_ww : numpy.ndarray
        Shape (N, 2, 2).
    wedges : _Wedges
        The wedges of the half turn, (N, K).
    across : bool
        ``v = n`` (else ``d``).

    Returns
    -------
    low, high : numpy.ndarray
        Range of ``m``, shape (N, 2 K, J), the wedges then their opposites, events ordered as
        :func:`_event_misses`; ``low > high`` where the event misses the wedge.
    var_low, var_high : numpy.ndarray
        Range of ``s^2``, widened by a relative ``_WIDENING`` of its scale, shape (N, 2 K, 1).

    """
    strips = bool(split.reach.any())
    var_constant, var_coefficients = _quadratic_coefficients(split.cov, across)
    single, double = [_linear_coefficients(split.mean, across)], [var_coefficients]
    if strips:
        speed = np.hypot(mu_w[:, 0], mu_w[:, 1])
        direction = np.where((speed > 0.0)[:, None], mu_w / np.where(speed > 0.0, speed, 1.0)[
            :, None], np.array([1.0, 0.0]))
        gain_constant, gain_coefficients = _gain_coefficients(split.gain, across)
        single += [direction, _linear_coefficients(
            split.mean - np.einsum('nij,nj->ni', split.gain, mu_w), across)]
        double.append(gain_coefficients)
    low, high = harmonic_ranges(wedges.start, wedges.width, single, double)
    count = len(single)
    # (S + D, N, 2 K, 1): the linear ranges negated on the opposite wedges, the others repeated.
    low, high = (np.concatenate([low, np.concatenate([-high[:count], low[count:]])],
                                axis=2)[..., None],
                 np.concatenate([high, np.concatenate([-low[:count], high[count:]])],
                                axis=2)[..., None])
    widening = (_WIDENING * split.scale_sq)[:, None, None]
    var_low = var_constant[:, None, None] + low[count] - widening
    var_high = var_constant[:, None, None] + high[count] + widening
    disc_reach = split.reach[:, None, None] * np.array(DISC_SIZES)
    ranges = [(low[0] - disc_reach, high[0] + disc_reach)]
    if strips:
        spread = np.sqrt(np.maximum(np.einsum('ni,nij,nj->n', direction, cov_ww,
                                              direction), 0.0))
        extent = spread[:, None, None] * np.array(STRIP_SIZES)
        l_low, l_high = _strip_lengths(low[1], high[1], speed[:, None, None] - extent,
                                       speed[:, None, None] + extent)
        product_low, product_high = _interval_product(
            l_low, l_high, gain_constant[:, None, None] + low[count + 1],
            gain_constant[:, None, None] + high[count + 1])
        missed = l_low > l_high
        ranges.append((np.where(missed, np.inf, low[2] + product_low),
                       np.where(missed, -np.inf, high[2] + product_high)))
    return (np.concatenate([low for low, _ in ranges], axis=2),
            np.concatenate([high for _, high in ranges], axis=2), var_low, var_high)


def _event_misses(strips):
    """Probabilities that the events miss, in the order of :func:`_ranges`, shape (J,)."""
    return np.concatenate([_DISC_MISSES, _STRIP_MISSES]) if strips else _DISC_MISSES


def folded_normal_minima(low, high, var_low, var_high, radius):
    """
    Lower bounds on ``F = P(|X| >= R)``, ``X ~ N(m, s^2)``, over boxes of ``m`` and ``s^2``.

    ``1 - F`` is the probability of the band ``|X| < R``,
    ``Phi((R - |m|) / s) - Phi((-R - |m|) / s)``, which decreases in ``|m|``: it is largest at the
    smallest ``|m|`` of the box, ``a`` (0 if ``m`` may change sign). There its first term is
    largest at the smallest ``s`` when ``a <= R`` (else at the largest) and its second smallest
    at the smallest ``s``. An empty box (``low > high``) gives 1.

    Parameters
    ----------
    low, high : numpy.ndarray
        Range of ``m``, shape (N, K, J).
    var_low, var_high : numpy.ndarray
        Range of ``s^2``, shape (N, K, 1), already widened.
    radius : numpy.ndarray
        ``R``, shape (N,).

    Returns
    -------
    numpy.ndarray
        Shape (N, K, J).

    """
    closest = np.where((low <= 0.0) & (high >= 0.0), 0.0, np.minimum(np.abs(low), np.abs(high)))
    closest = np.maximum(closest - _WIDENING * _finite_size(low, high), 0.0)
    sd_low, sd_high = np.sqrt(np.maximum(var_low, 0.0)), np.sqrt(np.maximum(var_high, 0.0))
    radius = radius[:, None, None]
    near_side = radius - closest
    near_cdf, far_cdf = ndtr(np.stack([
        _ratio(near_side, np.where(near_side >= 0.0, sd_low, sd_high), 0.0),
        _ratio(-radius - closest, sd_low, -np.inf)]))
    band = near_cdf - far_cdf
    return np.where(low > high, 1.0, np.clip(1.0 - band, 0.0, 1.0))


def half_normal_minima(low, high, var_low, var_high):
    """
    Lower bounds on ``G = P(X >= 0)``, ``X ~ N(m, s^2)``, over boxes of ``m`` and ``s^2``.

    ``Phi(m / s)`` at the smallest ``m``, and at the largest ``s`` if that ``m >= 0`` (else at the
    smallest). Shapes as for :func:`folded_normal_minima`; an empty box gives 1.
    """
    smallest = low - _WIDENING * _finite_size(low, high)
    sd_low, sd_high = np.sqrt(np.maximum(var_low, 0.0)), np.sqrt(np.maximum(var_high, 0.0))
    value = ndtr(_ratio(smallest, np.where(smallest >= 0.0, sd_high, sd_low), np.inf))
    return np.where(low > high, 1.0, value)


def _finite_size(low, high):
    """``max(|low|, |high|)`` where finite, else 0: the scale the rounding of a range has."""
    size = np.maximum(np.abs(low), np.abs(high))
    return np.where(np.isfinite(size), size, 0.0)


def _wedge_bound(mean, cov, radius, wedges):
    """
    Return the wedge bound of ``f`` (given ``radius``, (N,)) or of ``g``, and where it applies.

    ``mean`` (N, 4), ``cov`` (N, 4, 4) and their :class:`_Wedges`; results (N,). The shift is
    ``T = -lambda I`` for ``f`` and ``kappa J`` for ``g``, the conditional probability bounded on
    the boxes :func:`folded_normal_minima` or :func:`half_normal_minima`. The true masses are at
    least the wedges' and sum to one, so the conditional probability averages to at least
    ``sum q_k F_k + (1 - sum q_k) min F``; masses that sum above one by rounding are scaled down
    (they stay lower bounds). Each event's miss probability is then subtracted, and the best
    event kept.
    """
    cov_ww = cov[:, 2:, 2:]
    trace = _safe_trace(cov_ww, ~cov_ww.any(axis=(1, 2)))
    if radius is None:
        shift = ((cov[:, 0, 3] - cov[:, 1, 2]) / trace)[:, None, None] * _QUARTER_TURN
    else:
        shift = -((cov[:, 0, 2] + cov[:, 1, 3]) / trace)[:, None, None] * np.eye(2)
    split = _split(mean, cov, shift, wedges.invertible)
    ranges = _ranges(split, mean[:, 2:], cov_ww, wedges, radius is not None)
    minima = (half_normal_minima(*ranges) if radius is None
              else folded_normal_minima(*ranges, radius))
    masses = wedges.masses / np.maximum(wedges.masses.sum(axis=1), 1.0)[:, None]
    claimed = np.einsum('nk,nkj->nj', masses, minima)
    average = claimed + (1.0 - masses.sum(axis=1))[:, None] * minima.min(axis=1)
    return (np.max(average - _event_misses(bool(split.reach.any())), axis=1) - SLACK,
            split.usable)


def _cantelli(expectation, variance):
    """Cantelli's ``k^2 / (1 + k^2)`` of ``k = E / sd`` (0 when ``E < 0``; 1 when exact)."""
    expectation_sq = expectation * expectation
    with np.errstate(divide='ignore', invalid='ignore'):
        bound = expectation_sq / (expectation_sq + np.maximum(variance, 0.0))
    return np.where(expectation >= 0.0, np.where(np.isnan(bound), 1.0, bound), 0.0) - SLACK


def _validated(mean, cov, wedges):
    """Check the arguments; return ``mean`` (N, 4), ``cov`` (N, 4, 4) and the batch shape."""
    mean = np.asarray(mean, dtype=float)
    cov = np.asarray(cov, dtype=float)
    if mean.shape[-1:] != (4,) or cov.shape[-2:] != (4, 4):
        raise ValueError(f'mean must have shape (..., 4) and cov (..., 4, 4), got '
                         f'{mean.shape} and {cov.shape}')
    if not (np.isfinite(mean).all() and np.isfinite(cov).all()):
        raise ValueError('mean and cov must be finite')
    if (isinstance(wedges, bool) or not isinstance(wedges, (int, np.integer))
            or not MIN_WEDGES <= wedges <= MAX_WEDGES or wedges % 2):
        raise ValueError(f'wedges must be an even integer in [{MIN_WEDGES}, {MAX_WEDGES}], '
                         f'got {wedges!r}')
    shape = np.broadcast_shapes(mean.shape[:-1], cov.shape[:-2])
    return (np.broadcast_to(mean, shape + (4,)).reshape(-1, 4),
            np.broadcast_to(cov, shape + (4, 4)).reshape(-1, 4, 4), shape)


def _assemble(shape, deterministic, known, known_probability, wedge_probability, usable,
              cantelli_probability, holds):
    """Pick each entry's bound and its method; see :class:`Certificate`."""
    general = ~(deterministic | known)
    use_wedge = general & usable & (wedge_probability > cantelli_probability)
    probability = np.where(use_wedge, wedge_probability, cantelli_probability)
    probability = np.where(known, known_probability, probability)
    probability = np.where(deterministic, holds.astype(float), probability)
    method = np.select([deterministic, known, use_wedge], list(METHODS[:3]), METHODS[3])
    return Certificate(probability=np.clip(probability, 0.0, 1.0).reshape(shape),
                       method=method.reshape(shape))


def _safe_trace(cov_ww, degenerate):
    """``tr S_ww``, 1 where the wedge bound is not used (so that no division fails)."""
    return np.where(degenerate, 1.0, cov_ww[:, 0, 0] + cov_ww[:, 1, 1])


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
    radius = np.broadcast_to(np.asarray(radius, dtype=float), shape).reshape(-1)
    return _rvo(mean, cov, radius, *_wedge_bound(mean, cov, radius, _wedges(mean, cov, wedges)),
                shape)


def _rvo(mean, cov, radius, wedge_probability, usable, shape):
    """
    Return :func:`rvo_certificate` given the wedge bound of each entry.

    ``mean`` (N, 4), ``cov`` (N, 4, 4), ``radius``, ``wedge_probability`` and where it applies,
    ``usable``, (N,) each.
    """
    mu_r, mu_w = mean[:, :2], mean[:, 2:]
    cov_rr, cov_ww = cov[:, :2, :2], cov[:, 2:, 2:]
    deterministic = ~cov.any(axis=(1, 2))
    cross = mu_r[:, 0] * mu_w[:, 1] - mu_r[:, 1] * mu_w[:, 0]
    holds = cross * cross - radius * radius * np.sum(mu_w * mu_w, axis=1) >= 0.0
    known = ~deterministic & ~cov_ww.any(axis=(1, 2))
    # Computed only if some entry needs it (a belief with a known velocity is rare).
    known_probability = _known_rvo(mu_r, mu_w, cov_rr, radius) if known.any() else 0.0
    expectation, variance = rvo_moments(mean, cov, radius)
    return _assemble(shape, deterministic, known, known_probability, wedge_probability, usable,
                     _cantelli(expectation, variance), holds)


def _known_rvo(mu_r, mu_w, cov_rr, radius):
    """
    ``P(f >= 0)`` less ``SLACK`` where ``S_ww = 0``, shape (N,).

    ``w = mu_w`` exactly, and ``f >= 0`` iff ``|r . n| >= R`` for ``mu_w``'s normal ``n``, a
    folded normal (``w = 0``: ``f = 0``).
    """
    speed = np.hypot(mu_w[:, 0], mu_w[:, 1])
    normal = np.stack([mu_w[:, 1], -mu_w[:, 0]], axis=1) / np.where(speed > 0.0, speed,
                                                                    1.0)[:, None]
    offset = np.sum(mu_r * normal, axis=1)
    spread = np.sqrt(np.maximum(np.einsum('ni,nij,nj->n', normal, cov_rr, normal), 0.0))
    folded = ndtr(np.stack([_ratio(offset - radius, spread, np.inf),
                            _ratio(-offset - radius, spread, np.inf)])).sum(axis=0)
    return np.where(speed > 0.0, folded - SLACK, 1.0)


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
    return _receding(mean, cov, *_wedge_bound(mean, cov, None, _wedges(mean, cov, wedges)),
                     shape)


def _receding(mean, cov, wedge_probability, usable, shape):
    """
    Return :func:`receding_certificate` given the wedge bound of each entry.

    ``mean`` (N, 4), ``cov`` (N, 4, 4), ``wedge_probability`` and where it applies, ``usable``,
    (N,) each.
    """
    mu_r, mu_w = mean[:, :2], mean[:, 2:]
    cov_rr, cov_rw, cov_ww = cov[:, :2, :2], cov[:, :2, 2:], cov[:, 2:, 2:]
    deterministic = ~cov.any(axis=(1, 2))
    closing = np.sum(mu_r * mu_w, axis=1)
    known = ~deterministic & ~cov_ww.any(axis=(1, 2))
    known_probability = 0.0
    if known.any():
        # S_ww = 0: g = r . mu_w is normal (w = 0: g = 0).
        spread = np.sqrt(np.maximum(np.einsum('ni,nij,nj->n', mu_w, cov_rr, mu_w), 0.0))
        known_probability = np.where(mu_w.any(axis=1),
                                     ndtr(_ratio(closing, spread, np.inf)) - SLACK, 1.0)
    # E[g] = tr S_rw + mu_r . mu_w; Var[g] = 2 tr(G S G S) + 4 mu' G S G mu, G = [[0, I], [I, 0]]
    # / 2 (docs/method.md, section 7).
    product = _HALF_SWAP @ cov
    variance = (2.0 * np.einsum('nij,nji->n', product, product)
                + 4.0 * np.einsum('ni,nij,nj->n', mean, product @ _HALF_SWAP, mean))
    return _assemble(shape, deterministic, known, known_probability, wedge_probability, usable,
                     _cantelli(cov_rw[:, 0, 0] + cov_rw[:, 1, 1] + closing, variance),
                     closing >= 0.0)


def condition_bound(mean, cov, radius, required, gated, horizon=None, wedges=DEFAULT_WEDGES):
    """
    Certified lower bound on the accepted condition's probability, computed as far as needed.

    The planner's bound on ``P(f >= 0 or g >= 0 or (h1 >= 0 and h2 >= 0))`` for a neighbour: the
    bound of :func:`rvo_certificate` on ``P(f >= 0)``; where that falls short of ``required``
    and the gate counts (``gated``), the larger with :func:`receding_certificate`'s on
    ``P(g >= 0)``; and where that too falls short and the horizon is finite, the larger with
    :func:`horizon_certificate`'s on the whole condition. Each is a lower bound on the
    condition's probability, so the largest is one. A later bound is computed only for the
    entries the earlier ones leave short, and on exactly those (an entry's bound depends on the
    batch it is computed in only by rounding and by which events are tried, see
    :func:`_ranges`, so the batches are the ones the three functions would be called with).
    The wedges and their masses depend on ``w`` alone: ``f`` and ``g`` share them.

    Parameters
    ----------
    mean : array_like
        Mean of ``z``, shape (N, 4).
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
    mean, cov, shape = _validated(mean, cov, wedges)
    radius = np.broadcast_to(np.asarray(radius, dtype=float), shape).reshape(-1)
    required = np.broadcast_to(np.asarray(required, dtype=float), shape).reshape(-1)
    gated = np.flatnonzero(np.broadcast_to(gated, shape))
    cut = _wedges(mean, cov, wedges)
    bounds = _rvo(mean, cov, radius, *_wedge_bound(mean, cov, radius, cut), shape).probability
    gate = gated[bounds[gated] < required[gated]]
    if gate.size:
        mean_gate, cov_gate = mean[gate], cov[gate]
        bounds[gate] = np.maximum(bounds[gate], _receding(
            mean_gate, cov_gate, *_wedge_bound(mean_gate, cov_gate, None, cut.take(gate)),
            gate.shape).probability)
    horizon_rows = gate[bounds[gate] < required[gate]]
    if horizon is not None and horizon_rows.size:
        bounds[horizon_rows] = np.maximum(bounds[horizon_rows], horizon_certificate(
            mean[horizon_rows], cov[horizon_rows], radius[horizon_rows], horizon))
    return bounds


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
    radius = np.broadcast_to(np.asarray(radius, dtype=float), shape).reshape(-1)
    horizon = np.broadcast_to(np.asarray(horizon, dtype=float), shape).reshape(-1)
    if not (np.isfinite(horizon).all() and (horizon > 0.0).all()):
        raise ValueError('horizon must be finite and > 0')
    tau = horizon[:, None, None]
    mu_r = mean[:, :2]
    mu_p = mu_r + horizon[:, None] * mean[:, 2:]
    cov_rw = cov[:, :2, 2:]
    cov_pp = (cov[:, :2, :2] + tau * (cov_rw + cov_rw.transpose(0, 2, 1))
              + tau * tau * cov[:, 2:, 2:])
    angles = np.concatenate([
        np.broadcast_to(_HORIZON_ANGLES, (mean.shape[0], _HORIZON_ANGLES.size)),
        np.arctan2(np.stack([mu_r[:, 1], mu_p[:, 1]], axis=1),
                   np.stack([mu_r[:, 0], mu_p[:, 0]], axis=1))], axis=1)
    bisector = 0.5 * (angles[:, -2] + angles[:, -1])
    bisector = np.where(np.abs(angles[:, -2] - angles[:, -1]) > math.pi, bisector + math.pi,
                        bisector)
    angles = np.concatenate([angles, bisector[:, None]], axis=1)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    tails = []
    for mu, spread in ((mu_r, cov[:, :2, :2]), (mu_p, cov_pp)):
        along = np.einsum('nai,ni->na', directions, mu) - radius[:, None]
        sd = np.sqrt(np.maximum(np.einsum('nai,nij,naj->na', directions, spread, directions),
                                0.0))
        # An end exactly on the line with no spread still lies in the closed half-plane.
        tails.append(ndtr(-_ratio(along, sd, np.inf)))
    bound = np.max(1.0 - tails[0] - tails[1], axis=1) - SLACK
    return np.clip(bound, 0.0, 1.0).reshape(shape)
