"""
The closed-form moments of the conditions compiled (:mod:`.moments`).

Four numba functions, each compiled for one signature when this module is first imported
(:mod:`.moments` imports it on its first call; the planner's warm-up makes that call before the
node spins) and kept in numba's on-disk cache, as the ray search, the certificate and the walls
are (``./run.sh setup`` compiles every kernel module once after installing):
:func:`condition_moments`, the moments at given commands; :func:`condition_polynomials`, the
same on the ray polynomials' grid and their fit onto the bivariate quadratic and quartic; and
:func:`condition_margins`, the margins met at given commands (with the ray search's
:func:`.ray_search.achieved_margins`); and :func:`reach_weights`, the weight of the reach
condition, which the others apply themselves.

Per neighbour it forms the quadratic-form matrices and traces of :mod:`.moments`' docstring
(``A, ASA, (AS)^2 A, (AS)^3 A, ASB, (AS)^2 B, ASBSA, B, BSB`` for ``f``, ``X, XSX`` for each
quadratic-form condition ``X``), in 4 x 4 products of scalars; then at every commanded velocity
it takes ``mu'X mu`` of each and assembles the cumulants. numpy did the same as a few dozen
calls on (N, F, 4, 4) arrays, each of a few microseconds whatever N, and a plan makes several
such calls (the ray polynomials' grid, the anchors, the chosen velocity, Cantelli's floor of
the certificate).
"""

import math

from numba import types
import numpy as np

from .moments import REACH_WEIGHT_BOUNDS
from .ray_search import achieved_margins
from .ray_solver import READ_ONLY_CUBE, READ_ONLY_FLAGS, READ_ONLY_ROWS, READ_ONLY_VECTOR, jit

# q = r x u = z'Az, p = |u|^2 = z'Bz, g = r . u = z'Gz, |r|^2 = z'Pz.
_CROSS = np.array([[0.0, 0.0, 0.0, 0.5],
                   [0.0, 0.0, -0.5, 0.0],
                   [0.0, -0.5, 0.0, 0.0],
                   [0.5, 0.0, 0.0, 0.0]])
_SPEED = np.diag([0.0, 0.0, 1.0, 1.0])
_DOT = np.array([[0.0, 0.0, 0.5, 0.0],
                 [0.0, 0.0, 0.0, 0.5],
                 [0.5, 0.0, 0.0, 0.0],
                 [0.0, 0.5, 0.0, 0.0]])
_POSITION = np.diag([1.0, 1.0, 0.0, 0.0])
# The matrices of f's quadratic forms, then X and XSX of each of the (up to) four
# quadratic-form conditions g, h1, h2, h3; the traces of f, then tr XS and tr XSXS of each.
_RVO_FORMS = 9
_RVO_TRACES = 8
_EXTRA_CONDITIONS = 4
# The first six monomials of the bivariate quartic (moments._EXPONENTS) have degree <= 2.
_QUADRATIC_TERMS = 6

_LOWEST_WEIGHT, _HIGHEST_WEIGHT = REACH_WEIGHT_BOUNDS

_CUBE = types.float64[:, :, ::1]
_MOMENTS_SIGNATURE = types.Tuple((_CUBE, _CUBE))(
    READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_VECTOR,
    READ_ONLY_VECTOR, types.boolean, types.boolean)
_POLYNOMIALS_SIGNATURE = types.Tuple((_CUBE, _CUBE))(
    READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_VECTOR,
    READ_ONLY_VECTOR, types.boolean, types.boolean, READ_ONLY_ROWS)
_MARGINS_SIGNATURE = types.float64[:, ::1](
    READ_ONLY_ROWS, READ_ONLY_CUBE, READ_ONLY_VECTOR, READ_ONLY_CUBE, READ_ONLY_VECTOR,
    READ_ONLY_VECTOR, types.boolean, types.boolean, READ_ONLY_FLAGS)
_WEIGHTS_SIGNATURE = types.float64[::1](READ_ONLY_ROWS, READ_ONLY_VECTOR)


@jit()
def _product(left, right, out):
    """Write the 4 x 4 product ``left @ right`` into ``out``, each sum in index order."""
    for row in range(4):
        for column in range(4):
            total = left[row, 0] * right[0, column]
            for inner in range(1, 4):
                total += left[row, inner] * right[inner, column]
            out[row, column] = total


@jit()
def _copy(source, out):
    """Write the 4 x 4 matrix ``source`` into ``out``."""
    for row in range(4):
        for column in range(4):
            out[row, column] = source[row, column]


@jit()
def _trace_product(left, right):
    """Return ``tr(left @ right) = sum_ij left_ij right_ji`` of two 4 x 4 matrices."""
    total = 0.0
    for row in range(4):
        for column in range(4):
            total += left[row, column] * right[column, row]
    return total


@jit()
def _form(matrix, m0, m1, m2, m3):
    """Return the quadratic form ``mu' X mu`` of ``mu = (m0, m1, m2, m3)``, row by row."""
    total = m0 * (matrix[0, 0] * m0 + matrix[0, 1] * m1 + matrix[0, 2] * m2 + matrix[0, 3] * m3)
    total += m1 * (matrix[1, 0] * m0 + matrix[1, 1] * m1 + matrix[1, 2] * m2 + matrix[1, 3] * m3)
    total += m2 * (matrix[2, 0] * m0 + matrix[2, 1] * m1 + matrix[2, 2] * m2 + matrix[2, 3] * m3)
    total += m3 * (matrix[3, 0] * m0 + matrix[3, 1] * m1 + matrix[3, 2] * m2 + matrix[3, 3] * m3)
    return total


@jit()
def _reach_weight(x, y, radius):
    """Return ``1 - R / |mu_r|`` within `REACH_WEIGHT_BOUNDS` (NaN: the lower bound)."""
    weight = 1.0 - radius / math.hypot(x, y)
    if weight != weight:
        return _LOWEST_WEIGHT
    return min(max(weight, _LOWEST_WEIGHT), _HIGHEST_WEIGHT)


@jit(_WEIGHTS_SIGNATURE)
def reach_weights(origin, radius):
    """
    Return the weight ``eps`` of each neighbour's reach condition ``h3``, shape (N,).

    ORIGIN (N, 4) is the mean of ``z`` (its first two components the relative position's),
    RADIUS (N,) ``R``: ``1 - R / |mu_r|`` within `REACH_WEIGHT_BOUNDS`.
    """
    weights = np.empty(origin.shape[0])
    for neighbour in range(origin.shape[0]):
        weights[neighbour] = _reach_weight(origin[neighbour, 0], origin[neighbour, 1],
                                           radius[neighbour])
    return weights


@jit(_MOMENTS_SIGNATURE)
def condition_moments(origin, cov, radius, velocities, horizon, lead, gate, finite):
    """
    Mean and variance of every condition of every neighbour at given commanded velocities.

    The conditions are, in order: ``f``; ``g`` if ``gate``; ``h1``, ``h2`` and ``h3`` if
    ``finite`` (docs/method.md, sections 3 and 7), with

    * ``E[f] = k2 + k1^2 - R^2 E[p]`` and ``Var[f] = k4 + 4 k3 k1 + 2 k2^2 + 4 k2 k1^2 - 2 R^2
      (k(q, q, p) + 2 k1 k(q, p)) + R^4 Var[p]`` from the joint cumulants of ``q = z'Az`` and
      ``p = z'Bz`` (:mod:`.moments`' docstring);
    * ``E[z'Xz] = tr XS + mu'X mu`` and ``Var[z'Xz] = 2 tr XSXS + 4 mu'XSX mu`` for
      ``X`` = ``G``, ``H1 = -G - tau B``, ``H2 = P + 2 tau G + tau^2 B`` and ``H3 = (1 - eps)
      (P - tau^2 / eps B)``, less ``R^2`` from the means of ``h2`` and ``h3``.

    Parameters
    ----------
    origin : numpy.ndarray
        Mean of ``z`` at ``v_c = 0``, shape (N, 4).
    cov : numpy.ndarray
        Covariance ``S`` of ``z``, shape (N, 4, 4).
    radius : numpy.ndarray
        ``R`` per neighbour, shape (N,).
    velocities : numpy.ndarray
        Commanded velocities ``v_c`` per neighbour, shape (N, P, 2), or shared, (1, P, 2): the
        mean of ``z`` at one is ``origin`` plus ``lead v_c`` in the velocity components.
    horizon : numpy.ndarray
        ``tau`` per neighbour, shape (N,), or shared, (1,); read only if ``finite``. ``h3``'s
        ``eps`` is :func:`reach_weights`'.
    lead : numpy.ndarray
        ``1 / rho`` per neighbour, shape (N,), or shared, (1,).
    gate, finite : bool
        Whether ``g`` is a condition; whether ``h1``, ``h2`` and ``h3`` are.

    Returns
    -------
    means, variances : numpy.ndarray
        Shape (N, P, C) each, ``C = 1 + gate + 3 finite``.

    """
    count, points = origin.shape[0], velocities.shape[1]
    shared = velocities.shape[0] == 1
    extras = (1 if gate else 0) + (3 if finite else 0)
    means = np.empty((count, points, 1 + extras))
    variances = np.empty((count, points, 1 + extras))
    # The quadratic-form matrices X (A and B, then the conditions'), their XS, XSX, tr XS and
    # tr XSXS; f's nine matrices and eight traces.
    left = np.empty((_EXTRA_CONDITIONS + 2, 4, 4))
    form_cov = np.empty((_EXTRA_CONDITIONS + 2, 4, 4))
    sandwich = np.empty((_EXTRA_CONDITIONS + 2, 4, 4))
    rvo = np.empty((_RVO_FORMS, 4, 4))
    cross_cov_2 = np.empty((4, 4))
    cross_speed = np.empty((4, 4))
    traces = np.empty(_RVO_TRACES)
    form_traces = np.empty(_EXTRA_CONDITIONS + 2)
    squared_traces = np.empty(_EXTRA_CONDITIONS + 2)
    _copy(_CROSS, left[0])
    _copy(_SPEED, left[1])
    # Rows of `left`: A and B (always used), G, H1, H2, H3; the conditions are rows first to
    # last - 1 (G only with the gate, the H's only with a finite horizon).
    first = 2 if gate else 3
    last = 6 if finite else 3
    _copy(_DOT, left[2])
    for neighbour in range(count):
        if finite:
            tau = horizon[neighbour if horizon.shape[0] > 1 else 0]
            weight = _reach_weight(origin[neighbour, 0], origin[neighbour, 1],
                                   radius[neighbour])
            for row in range(4):
                for column in range(4):
                    left[3, row, column] = -_DOT[row, column] - tau * _SPEED[row, column]
                    left[4, row, column] = (_POSITION[row, column] + 2.0 * tau * _DOT[row, column]
                                            + tau * tau * _SPEED[row, column])
                    left[5, row, column] = (1.0 - weight) * (
                        _POSITION[row, column] - tau * tau / weight * _SPEED[row, column])
        matrix = cov[neighbour]
        for index in range(last):
            if index < 2 or index >= first:
                _product(left[index], matrix, form_cov[index])
                _product(form_cov[index], left[index], sandwich[index])
                x_cov = form_cov[index]
                form_traces[index] = x_cov[0, 0] + x_cov[1, 1] + x_cov[2, 2] + x_cov[3, 3]
                squared_traces[index] = _trace_product(x_cov, x_cov)
        cross_cov, speed_cov = form_cov[0], form_cov[1]
        _product(cross_cov, cross_cov, cross_cov_2)
        _product(cross_cov, speed_cov, cross_speed)
        _copy(_CROSS, rvo[0])
        _copy(sandwich[0], rvo[1])
        _product(cross_cov_2, _CROSS, rvo[2])
        _product(cross_cov_2, sandwich[0], rvo[3])
        _product(cross_cov, _SPEED, rvo[4])
        _product(cross_cov_2, _SPEED, rvo[5])
        _product(cross_speed, _CROSS, rvo[6])
        _copy(_SPEED, rvo[7])
        _copy(sandwich[1], rvo[8])
        traces[0] = form_traces[0]
        traces[1] = squared_traces[0]
        traces[2] = _trace_product(cross_cov_2, cross_cov)
        traces[3] = _trace_product(cross_cov_2, cross_cov_2)
        traces[4] = cross_speed[0, 0] + cross_speed[1, 1] + cross_speed[2, 2] + cross_speed[3, 3]
        traces[5] = _trace_product(cross_cov_2, speed_cov)
        traces[6] = form_traces[1]
        traces[7] = squared_traces[1]
        radius_sq = radius[neighbour] * radius[neighbour]
        m0, m1 = origin[neighbour, 0], origin[neighbour, 1]
        commands = velocities[0] if shared else velocities[neighbour]
        factor = lead[neighbour if lead.shape[0] > 1 else 0]
        for point in range(points):
            m2 = origin[neighbour, 2] + factor * commands[point, 0]
            m3 = origin[neighbour, 3] + factor * commands[point, 1]
            k1 = traces[0] + _form(rvo[0], m0, m1, m2, m3)
            k2 = 2.0 * traces[1] + 4.0 * _form(rvo[1], m0, m1, m2, m3)
            k3 = 8.0 * traces[2] + 24.0 * _form(rvo[2], m0, m1, m2, m3)
            k4 = 48.0 * traces[3] + 192.0 * _form(rvo[3], m0, m1, m2, m3)
            k_qp = 2.0 * traces[4] + 4.0 * _form(rvo[4], m0, m1, m2, m3)
            k_qqp = (8.0 * traces[5] + 16.0 * _form(rvo[5], m0, m1, m2, m3)
                     + 8.0 * _form(rvo[6], m0, m1, m2, m3))
            mean_p = traces[6] + _form(rvo[7], m0, m1, m2, m3)
            var_p = 2.0 * traces[7] + 4.0 * _form(rvo[8], m0, m1, m2, m3)
            k1_sq = k1 * k1
            means[neighbour, point, 0] = k2 + k1_sq - radius_sq * mean_p
            variances[neighbour, point, 0] = (
                k4 + 4.0 * k3 * k1 + 2.0 * k2 * k2 + 4.0 * k2 * k1_sq
                - 2.0 * radius_sq * (k_qqp + 2.0 * k1 * k_qp) + radius_sq * radius_sq * var_p)
            column = 1
            for index in range(first, last):
                means[neighbour, point, column] = form_traces[index] + _form(
                    left[index], m0, m1, m2, m3)
                if index >= 4:
                    # h2 = |r + tau u|^2 - R^2, h3 = (1 - eps) (|r|^2 - tau^2 |u|^2 / eps) - R^2.
                    means[neighbour, point, column] -= radius_sq
                variances[neighbour, point, column] = (
                    4.0 * _form(sandwich[index], m0, m1, m2, m3) + 2.0 * squared_traces[index])
                column += 1
    return means, variances


@jit(_POLYNOMIALS_SIGNATURE)
def condition_polynomials(origin, cov, radius, velocities, horizon, lead, gate, finite, fit):
    """
    Coefficients of every condition's mean and variance in the command, fitted on a grid.

    The moments of :func:`condition_moments` at the grid VELOCITIES (N or 1, G, 2), then per
    neighbour and condition the products ``fit[:Q] @ means`` and ``fit @ variances`` with FIT
    (F, G) the least-squares inverse of the grid's Vandermonde matrix, each sum in index order;
    ``Q`` = 6, the quadratic terms of the mean.

    Returns
    -------
    means, variances : numpy.ndarray
        Shape (N, 6, C) and (N, F, C).

    """
    means, variances = condition_moments(origin, cov, radius, velocities, horizon, lead, gate,
                                         finite)
    count, points, conditions = means.shape
    terms = fit.shape[0]
    mean_fit = np.empty((count, _QUADRATIC_TERMS, conditions))
    variance_fit = np.empty((count, terms, conditions))
    for neighbour in range(count):
        for term in range(terms):
            for condition in range(conditions):
                total = 0.0
                for point in range(points):
                    total += fit[term, point] * variances[neighbour, point, condition]
                variance_fit[neighbour, term, condition] = total
                if term < _QUADRATIC_TERMS:
                    total = 0.0
                    for point in range(points):
                        total += fit[term, point] * means[neighbour, point, condition]
                    mean_fit[neighbour, term, condition] = total
    return mean_fit, variance_fit


@jit(_MARGINS_SIGNATURE)
def condition_margins(origin, cov, radius, velocities, horizon, lead, gate, finite, enabled):
    """
    Return the margin ``k`` met at each command against each neighbour, shape (P, N).

    The moments of :func:`condition_moments` at the commands VELOCITIES (N or 1, P, 2), then
    :func:`.ray_search.achieved_margins` of every (neighbour, command) with the gate where
    ENABLED (N,) and the horizon conditions if FINITE.
    """
    means, variances = condition_moments(origin, cov, radius, velocities, horizon, lead, gate,
                                         finite)
    count, points, conditions = means.shape
    gated = np.empty(count * points, dtype=np.bool_)
    for neighbour in range(count):
        for point in range(points):
            gated[neighbour * points + point] = enabled[neighbour]
    margins = achieved_margins(means.reshape(count * points, conditions),
                               variances.reshape(count * points, conditions), gated, gate,
                               finite)
    out = np.empty((points, count))
    for neighbour in range(count):
        for point in range(points):
            out[point, neighbour] = margins[neighbour * points + point]
    return out
