"""
Feasible speed sets along candidate rays: exact (quartic) and Taylor (quadratic) solvers.

Along a ray the commanded velocity is ``t v_max e`` with ``t`` in [0, 1]; each condition has a
mean polynomial (degree <= 2) and a variance polynomial (degree <= 4) in ``t``
(:func:`prvo_planner.core.moments.ray_polynomials`). A solver returns breakpoints in
(0, 1); between consecutive breakpoints the acceptance of every condition is constant, so it is
decided by evaluating the conditions at the midpoint. Roots are found in closed form, vectorised
over all pairs, and polished by a Newton step; a root missed by rounding can only shift a
boundary by rounding-level amounts because acceptance is always re-evaluated exactly.
"""

import math

import numpy as np

from .moments import poly_eval

# Leading coefficients below this (relative to the largest one, on t in [0, 1]) are treated as
# zero: dropping them moves the polynomial by at most this much there, and a Newton step on the
# full polynomial (which squares a root's relative error) removes the resulting root error.
_DEGREE_TOLERANCE = 1e-7
# The derivative of coefficient-major quartics: their rows 1 to 4 times these, shape (4, 1).
_QUARTIC_DERIVATIVE_FACTORS = np.arange(1.0, 5.0)[:, None]


def quadratic_roots(constant, linear, quadratic):
    """
    Real roots of ``quadratic t^2 + linear t + constant``, robust to a vanishing leading term.

    Parameters
    ----------
    constant, linear, quadratic : numpy.ndarray
        Coefficients, same shape (...).

    Returns
    -------
    numpy.ndarray
        Roots, shape (..., 2), NaN where there is none.

    """
    scale = np.maximum(np.maximum(np.abs(constant), np.abs(linear)), np.abs(quadratic))
    scale = np.where(scale > 0.0, scale, 1.0)
    c0, c1, c2 = constant / scale, linear / scale, quadratic / scale
    with np.errstate(divide='ignore', invalid='ignore'):
        discriminant = c1 * c1 - 4.0 * c2 * c0
        root_disc = np.sqrt(np.where(discriminant >= 0.0, discriminant, np.nan))
        # half is never a difference of close numbers; with c2 = 0 the first root is -c0/c1.
        half = -0.5 * (c1 + np.where(c1 >= 0.0, root_disc, -root_disc))
        first = np.where(half != 0.0, c0 / half, np.where(c2 != 0.0, 0.0, np.nan))
        roots = np.stack([first, half / c2], axis=-1)
    return np.where(np.isfinite(roots), roots, np.nan)


def _depressed_cubic(b, c, d):
    """Depress ``t^3 + b t^2 + c t + d`` to ``x^3 + p x + q``, ``t = x + shift``."""
    return -b / 3.0, c - b * b / 3.0, (2.0 * b * b * b / 27.0) - b * c / 3.0 + d


def _cardano_root(p, q):
    """Return the real root of ``x^3 + p x + q`` when it is the only one (Cardano)."""
    discriminant = (0.5 * q) ** 2 + (p / 3.0) ** 3
    big = np.cbrt(-0.5 * q - np.copysign(np.sqrt(np.abs(discriminant)), q))
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(big != 0.0, big - p / (3.0 * big), 0.0), discriminant


def _monic_cubic_roots(b, c, d):
    """Real roots of ``t^3 + b t^2 + c t + d``, shape (..., 3), NaN for complex ones."""
    shift, p, q = _depressed_cubic(b, c, d)
    single, discriminant = _cardano_root(p, q)
    rho = np.sqrt(np.maximum(-p / 3.0, 0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        cosine = np.clip(np.where(rho > 0.0, -0.5 * q / rho ** 3, 0.0), -1.0, 1.0)
    theta = np.arccos(cosine)[..., None] / 3.0
    three = 2.0 * rho[..., None] * np.cos(theta - np.array([0.0, 2.0, 4.0]) * np.pi / 3.0)
    nan = np.full_like(single, np.nan)
    one_real = (discriminant > 0.0)[..., None]
    roots = np.where(one_real, np.stack([single, nan, nan], axis=-1), three)
    return roots + shift[..., None]


def _stable_quadratic_roots(linear, constant):
    """Real roots of ``t^2 + linear t + constant`` without cancellation, shape (2, ...)."""
    roots = np.empty((2,) + linear.shape)
    with np.errstate(invalid='ignore', divide='ignore'):
        half = -0.5 * (linear + np.copysign(np.sqrt(linear * linear - 4.0 * constant), linear))
        roots[0] = half
        np.divide(constant, half, out=roots[1])
    roots[1][half == 0.0] = 0.0
    return roots


def _monic_quartic_roots(b, c, d, e):
    """
    Real roots of ``t^4 + b t^3 + c t^2 + d t + e`` (Ferrari), shape (4, K), NaN for complex.

    The depressed quartic ``y^4 + p y^2 + q y + r`` (``t = y - b / 4``) factors as
    ``(y^2 + s y + m + p/2 - q/(2 s)) (y^2 - s y + m + p/2 + q/(2 s))`` with ``s = sqrt(2 m)``
    and ``m`` the largest root of the resolvent ``m^3 + p m^2 + (p^2/4 - r) m - q^2/8``,
    which is ``>= 0``. Where ``m`` vanishes (``q = 0``) the quartic is biquadratic instead.
    """
    shift = -0.25 * b
    b2 = b * b
    p = c - 0.375 * b2
    q = d - 0.5 * b * c + 0.125 * b2 * b
    r = e - 0.25 * b * d + 0.0625 * b2 * c - 0.01171875 * b2 * b2
    # The resolvent depressed by m = x - p/3: x^3 + P x + Q.
    p2 = p * p
    cubic_p = -p2 / 12.0 - r
    cubic_q = p * (r / 3.0 - p2 / 108.0) - 0.125 * q * q
    # One real root (Cardano) or three (the largest is the trigonometric one of angle 0).
    single, discriminant = _cardano_root(cubic_p, cubic_q)
    with np.errstate(invalid='ignore', divide='ignore'):
        rho = np.sqrt(np.maximum(-cubic_p / 3.0, 0.0))
        angle = np.arccos(np.clip(-0.5 * cubic_q / (rho * rho * rho), -1.0, 1.0))
        largest = np.where(discriminant > 0.0, single, 2.0 * rho * np.cos(angle / 3.0))
        m = np.maximum(largest - p / 3.0, 0.0)
        s = np.sqrt(2.0 * m)
        offset = np.where(s > 0.0, 0.5 * q / s, 0.0)
        base = 0.5 * p + m
        # Both factors at once: linear terms (s, -s), constants (base - offset, base + offset).
        linear, constant = np.empty((2, 2) + s.shape)
        linear[0] = s
        np.negative(s, out=linear[1])
        np.subtract(base, offset, out=constant[0])
        np.add(base, offset, out=constant[1])
        roots = _stable_quadratic_roots(linear, constant)
    roots = roots.reshape(4, -1)
    small_m = m <= 1e-12 * np.maximum(1.0, np.abs(p) + np.sqrt(np.abs(r)))
    if small_m.any():
        with np.errstate(invalid='ignore'):
            squares = np.sqrt(_stable_quadratic_roots(p[small_m], r[small_m]))
        roots[:, small_m] = np.concatenate([squares, -squares])
    return roots + shift


def _polish(columns, roots):
    """
    Newton-polish the roots (K, R) of polynomials with coefficient-major ``columns`` (L, K).

    Only roots within 2e-3 of [0, 1] are polished: the step moves a root by less than 1e-3, so
    no other root can enter (0, 1), where breakpoints matter.
    """
    near = np.abs(roots - 0.5) <= 0.5 + 2e-3
    row, column = near.nonzero()
    coefficients = columns[:, row]
    derivative = coefficients[1:] * _QUARTIC_DERIVATIVE_FACTORS
    points = roots[row, column]
    value, slope = coefficients[-1], derivative[-1]
    for power in range(coefficients.shape[0] - 2, -1, -1):
        value = value * points + coefficients[power]
        if power > 0:
            slope = slope * points + derivative[power - 1]
    with np.errstate(divide='ignore', invalid='ignore'):
        step = value / slope
    # A large step means a flat spot (near-double root): keep the closed-form value.
    points = np.where(np.abs(step) < 1e-3, points - step, points)
    roots[row, column] = points
    return roots


def _bernstein_matrix(degree):
    """Map ascending power coefficients on [0, 1] to Bernstein coefficients, (L, L)."""
    matrix = np.zeros((degree + 1, degree + 1))
    for power in range(degree + 1):
        for index in range(power, degree + 1):
            matrix[power, index] = math.comb(index, power) / math.comb(degree, power)
    return matrix


_BERNSTEIN = {degree: _bernstein_matrix(degree) for degree in (2, 4)}


def _product(matrix, columns):
    """
    ``matrix @ columns`` for coefficient-major (L, K) columns, each column's as if alone.

    A product with one column takes the matrix-vector routine, whose rounding differs from the
    matrix-matrix routine's; every column is computed by the latter, so a column's result does
    not depend on how many others share the product.
    """
    if columns.shape[1] == 1:
        return (matrix @ np.repeat(columns, 2, axis=1))[:, :1]
    return matrix @ columns


def bernstein_minimum(coefficients):
    """Smallest Bernstein coefficient (K,) of (L, K) polynomials: a lower bound on [0, 1]."""
    # Coefficient-major product and reduction: reducing along a short last axis is slow.
    return _product(_BERNSTEIN[coefficients.shape[0] - 1].T, coefficients).min(axis=0)


def _segment_bernstein_matrix(degree, segments):
    """
    Map ascending power coefficients to Bernstein coefficients on each of equal segments.

    On segment ``j``, ``[a, b] = [j, j + 1] / segments``, substituting ``t = a + (b - a) s``
    gives power coefficients in ``s`` on [0, 1], whose Bernstein coefficients bound the
    polynomial there. Returns shape (segments (degree + 1), degree + 1).
    """
    blocks = []
    for segment in range(segments):
        start, width = segment / segments, 1.0 / segments
        substitution = np.zeros((degree + 1, degree + 1))
        for power in range(degree + 1):
            for order in range(power + 1):
                substitution[order, power] = (math.comb(power, order) * start ** (power - order)
                                              * width ** order)
        blocks.append(_BERNSTEIN[degree].T @ substitution)
    return np.concatenate(blocks)


# Certificates are per segment of [0, 1]: a neighbour that rejects a whole segment of a ray
# closes it for every other neighbour, whose roots there need not be found.
SEGMENTS = 4
_SEGMENT_BERNSTEIN = {degree: _segment_bernstein_matrix(degree, SEGMENTS) for degree in (2, 4)}


# Columns per product of segment_certificates: a block's Bernstein coefficients stay in the
# processor's cache while they are compared.
_CERTIFICATE_BLOCK = 4096


def segment_certificates(coefficients):
    """
    Certify a constant sign on each of the ``SEGMENTS`` equal segments of [0, 1].

    A polynomial is a convex combination of its Bernstein coefficients on a segment, so all of
    them ``>= 0`` proves ``p >= 0`` there and all ``< 0`` proves ``p < 0``.

    Parameters
    ----------
    coefficients : numpy.ndarray
        Ascending coefficients, coefficient-major: shape (L, K) with L = 3 or 5.

    Returns
    -------
    nonnegative, negative : numpy.ndarray
        Booleans, shape (SEGMENTS, K).

    """
    length, count = coefficients.shape
    matrix = _SEGMENT_BERNSTEIN[length - 1]
    nonnegative = np.empty((SEGMENTS, count), dtype=bool)
    negative = np.empty((SEGMENTS, count), dtype=bool)
    # Blocks of at least two columns (see _product), the last one possibly longer.
    starts = list(range(0, max(count - 1, 1), _CERTIFICATE_BLOCK))
    for start, stop in zip(starts, starts[1:] + [count], strict=True):
        signs = (_product(matrix, coefficients[:, start:stop]) >= 0.0).reshape(
            SEGMENTS, length, -1)
        # All signs nonnegative, or none: and / or over the coefficients of each segment.
        every, some = signs[:, 0].copy(), signs[:, 0].copy()
        for index in range(1, length):
            every &= signs[:, index]
            some |= signs[:, index]
        nonnegative[:, start:stop] = every
        np.logical_not(some, out=negative[:, start:stop])
    return nonnegative, negative


def polynomial_roots(columns):
    """
    Real roots of polynomials of degree <= 4, vectorised, with degree detection.

    Parameters
    ----------
    columns : numpy.ndarray
        Ascending coefficients, coefficient-major: shape (5, K).

    Returns
    -------
    numpy.ndarray
        Real roots, shape (K, 4), NaN-padded.

    """
    columns = columns / np.abs(columns).max(axis=0)
    quartic = np.abs(columns[4]) > _DEGREE_TOLERANCE
    if quartic.all():
        monic = columns[:4] / columns[4]
        found = _monic_quartic_roots(monic[3], monic[2], monic[1], monic[0]).T
    else:
        found = np.full((columns.shape[1], 4), np.nan)
        cubic = ~quartic & (np.abs(columns[3]) > _DEGREE_TOLERANCE)
        lower = ~quartic & ~cubic
        monic = columns[:4, quartic] / columns[4, quartic]
        found[quartic] = _monic_quartic_roots(monic[3], monic[2], monic[1], monic[0]).T
        monic = columns[:3, cubic] / columns[3, cubic]
        found[cubic, :3] = _monic_cubic_roots(monic[2], monic[1], monic[0])
        found[lower, :2] = quadratic_roots(columns[0, lower], columns[1, lower],
                                           columns[2, lower])
    return _polish(columns, found)


def taylor_quadratics(means, variances, margins, preferred):
    """
    Build the paper's quadratic surrogate ``mean(t) - k T(t)`` (docs/method.md, section 6).

    ``T`` is the second-order Taylor expansion of ``sigma = sqrt(variance)`` around ``t*``, the
    point of ``{t in [0, 1] : mean(t) >= 0}`` closest to the preferred ``t`` on the ray (the
    preferred ``t`` itself when that set is empty).

    Parameters
    ----------
    means, variances : numpy.ndarray
        Shapes (..., 3) and (..., 5).
    margins : numpy.ndarray
        ``k``, broadcastable to shape (...).
    preferred : numpy.ndarray
        Preferred ``t`` per ray, broadcastable to shape (...).

    Returns
    -------
    numpy.ndarray
        Quadratic coefficients, shape (..., 3).

    """
    preferred = np.clip(preferred, 0.0, 1.0)
    shape = means.shape[:-1]
    candidates = np.concatenate([
        np.broadcast_to(np.asarray(preferred)[..., None], shape + (1,)),
        np.clip(np.nan_to_num(quadratic_roots(means[..., 0], means[..., 1], means[..., 2]),
                              nan=0.0), 0.0, 1.0),
        np.zeros(shape + (1,)), np.ones(shape + (1,))], axis=-1)
    usable = poly_eval(means[..., None, :], candidates) >= 0.0
    distance = np.where(usable, np.abs(candidates - candidates[..., :1]), np.inf)
    centre = np.take_along_axis(candidates, np.argmin(distance, axis=-1)[..., None], -1)[..., 0]
    first = variances[..., 1:] * np.arange(1, 5)
    second = first[..., 1:] * np.arange(1, 4)
    variance = np.maximum(poly_eval(variances, centre), 0.0)
    sigma = np.sqrt(variance)
    slope_var = poly_eval(first, centre)
    curve_var = poly_eval(second, centre)
    with np.errstate(divide='ignore', invalid='ignore'):
        slope = np.where(sigma > 0.0, slope_var / (2.0 * sigma), 0.0)
        curve = np.where(sigma > 0.0,
                         curve_var / (2.0 * sigma) - slope_var ** 2 / (4.0 * sigma ** 3), 0.0)
    k = np.asarray(margins)
    return np.stack([
        means[..., 0] - k * (sigma - slope * centre + 0.5 * curve * centre ** 2),
        means[..., 1] - k * (slope - curve * centre),
        means[..., 2] - k * 0.5 * curve], axis=-1)
