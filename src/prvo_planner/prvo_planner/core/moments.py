"""
Closed-form moments of the RVO condition and of the receding, horizon and reach conditions.

With ``z = (r_x, r_y, u_x, u_y) ~ N(mu, S)`` every condition of docs/method.md is a quadratic
form ``z'Xz`` or, for ``f``, ``q^2 - R^2 p`` with quadratic forms ``q = r x u = z'Az`` and
``p = |u|^2 = z'Bz``. Joint cumulants of Gaussian quadratic forms have a closed form (from the
cumulant generating function ``-1/2 log det(I - 2 M S) + mu' (I - 2 M S)^-1 M mu``):

    k(z'X1 z, ..., z'Xn z) = 2^(n-1) [ (1/n) sum_perm tr(X1 S ... Xn S)
                                        + sum_perm mu' X1 S ... S Xn mu ]

so ``E[f] = k2(q) + k1(q)^2 - R^2 E[p]`` and

    Var[f] = k4 + 4 k3 k1 + 2 k2^2 + 4 k2 k1^2 - 2 R^2 (k(q,q,p) + 2 k1 k(q,p)) + R^4 Var[p].

Every term is a trace (independent of the mean) plus a quadratic form ``mu'Xmu``.

For the planner, ``E`` is a quadratic and ``Var`` a quartic polynomial in the commanded
velocity ``v_c`` (``mu_w = v_c / rho + mu_w(0)``, ``1 / rho = 2`` for RVO). Their coefficients
are recovered exactly (to rounding) by evaluating the closed form on a 5 x 5 Chebyshev grid over
``[-v_max, v_max]^2`` and applying a fixed least-squares inverse of the bivariate quartic
Vandermonde matrix (a well-conditioned, full-rank 25 x 15 system); restricted to a ray
``v_c = t v_max e`` they become polynomials in ``t`` by one matrix product with the direction
monomials. This costs a few
hundred closed-form evaluations per plan, independent of the number of directions.
"""

import functools
import math

import numpy as np

# q = r x u = z'Az, p = |u|^2 = z'Bz, g = r . u = z'Gz.
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

NUM_RVO_FORMS = 9
# The reach condition h3 (docs/method.md, section 7) trades |r|^2 against tau^2 |w|^2 by a
# weight eps in (0, 1), chosen per neighbour from its mean distance d as 1 - R / d (where h3
# is exact), within these bounds.
REACH_WEIGHT_BOUNDS = (0.05, 0.95)


def poly_eval(poly, t):
    """
    Evaluate polynomials at points by Horner's rule.

    Parameters
    ----------
    poly : numpy.ndarray
        Coefficients, shape (..., L), ascending powers.
    t : numpy.ndarray
        Points, broadcastable against shape (...).

    Returns
    -------
    numpy.ndarray
        Values, broadcast shape of (...) and ``t``.

    """
    value = poly[..., -1]
    for power in range(poly.shape[-1] - 2, -1, -1):
        value = value * t + poly[..., power]
    return value


@functools.lru_cache(maxsize=8)
def _form_lefts(time_horizon):
    """Return ``A, B, G`` and, with a finite horizon, ``H1, H2``: shape (3 or 5, 4, 4)."""
    left = [_CROSS, _SPEED, _DOT]
    if math.isfinite(time_horizon):
        tau = time_horizon
        left += [-_DOT - tau * _SPEED, _POSITION + 2.0 * tau * _DOT + tau ** 2 * _SPEED]
    left = np.stack(left)
    # Shared between calls: read-only so that no caller can alter the cached value.
    left.flags.writeable = False
    return left


def _horizon_lefts(time_horizon):
    """Return :func:`_form_lefts` of one horizon, or stacked per horizon of an array."""
    if np.ndim(time_horizon) == 0:
        return _form_lefts(time_horizon)
    horizons, inverse = np.unique(time_horizon, return_inverse=True)
    return np.stack([_form_lefts(float(horizon)) for horizon in horizons])[
        inverse.reshape(np.shape(time_horizon))]


def reach_weights(origin, combined_radius):
    """Return the weight ``eps`` of each neighbour's reach condition ``h3``, shape (N,).

    ORIGIN (N, 4) is the mean of ``z`` (its first two components the relative position's),
    COMBINED_RADIUS (N,) ``R``: ``1 - R / |mu_r|`` within `REACH_WEIGHT_BOUNDS`.
    """
    distance = np.hypot(origin[:, 0], origin[:, 1])
    with np.errstate(divide='ignore', invalid='ignore'):
        weight = 1.0 - combined_radius / distance
    return np.clip(np.nan_to_num(weight, nan=REACH_WEIGHT_BOUNDS[0]), *REACH_WEIGHT_BOUNDS)


def _reach_lefts(time_horizon, weights):
    """Return ``H3 = (1 - eps) P - (1 - eps) / eps tau^2 B`` per weight: shape (N, 4, 4)."""
    weights = np.asarray(weights, dtype=float)[:, None, None]
    horizon = np.reshape(time_horizon, (-1, 1, 1))
    return (1.0 - weights) * (_POSITION - horizon ** 2 / weights * _SPEED)


def form_matrices(cov, time_horizon=math.inf, weights=None):
    """
    Quadratic-form matrices and traces that the moments of every condition need.

    Only quadratic forms ``mu'X mu`` are taken of the matrices, so they are not symmetrised.

    Parameters
    ----------
    cov : numpy.ndarray
        Covariance ``S`` of ``z``, shape (N, 4, 4) (or (..., 4, 4) with an infinite horizon).
    time_horizon : float or numpy.ndarray
        ``tau``, or one per covariance, shape (N,), all finite or all infinite; ``h1``, ``h2``
        and ``h3`` are included only when it is finite.
    weights : numpy.ndarray
        With a finite horizon, ``h3``'s ``eps`` per covariance, shape (N,)
        (:func:`reach_weights`).

    Returns
    -------
    matrices : numpy.ndarray
        Shape (..., F, 4, 4): the nine of ``f``, ``A, ASA, (AS)^2 A, (AS)^3 A, ASB, (AS)^2 B,
        ASBSA, B, BSB``, then ``X, XSX`` for ``X`` = ``G`` (of ``g``) and, with a finite
        horizon, ``H1``, ``H2`` and ``H3``.
    traces : numpy.ndarray
        Shape (..., T): the eight of ``f``, ``tr AS, tr (AS)^2, tr (AS)^3, tr (AS)^4,
        tr ASBS, tr (AS)^2 BS, tr BS, tr (BS)^2``, then ``tr XS, tr XSXS`` per ``X`` as above.

    """
    left = _horizon_lefts(time_horizon)
    if np.isfinite(time_horizon).all():
        # H3 is each neighbour's own: the shared forms, then its.
        left = np.concatenate([np.broadcast_to(left, cov.shape[:1] + left.shape[-3:]),
                               _reach_lefts(time_horizon, weights)[:, None]], axis=1)
    # X S and X S X for every X at once: (..., K, 4, 4).
    form_cov = left @ cov[..., None, :, :]
    sandwich = form_cov @ left
    cross_cov, speed_cov = form_cov[..., 0, :, :], form_cov[..., 1, :, :]
    cross_cov_2 = cross_cov @ cross_cov
    cross_speed = cross_cov @ speed_cov
    extras = left.shape[-3] - 2
    matrices = np.empty(cov.shape[:-2] + (NUM_RVO_FORMS + 2 * extras, 4, 4))
    matrices[..., 0, :, :] = _CROSS
    matrices[..., 1, :, :] = sandwich[..., 0, :, :]
    matrices[..., 2, :, :] = cross_cov_2 @ _CROSS
    matrices[..., 3, :, :] = cross_cov_2 @ sandwich[..., 0, :, :]
    matrices[..., 4, :, :] = cross_cov @ _SPEED
    matrices[..., 5, :, :] = cross_cov_2 @ _SPEED
    matrices[..., 6, :, :] = cross_speed @ _CROSS
    matrices[..., 7, :, :] = _SPEED
    matrices[..., 8, :, :] = sandwich[..., 1, :, :]
    matrices[..., NUM_RVO_FORMS::2, :, :] = left[..., 2:, :, :]
    matrices[..., NUM_RVO_FORMS + 1::2, :, :] = sandwich[..., 2:, :, :]
    # tr XY = sum_ij X_ij Y_ji.
    form_traces = np.einsum('...kii->...k', form_cov)
    squared_traces = np.einsum('...kij,...kji->...k', form_cov, form_cov)
    rvo_traces = np.einsum('...kij,...kji->...k', cross_cov_2[..., None, :, :],
                           np.stack([cross_cov, cross_cov_2, speed_cov], axis=-3))
    traces = np.empty(cov.shape[:-2] + (8 + 2 * extras,))
    traces[..., 0] = form_traces[..., 0]
    traces[..., 1] = squared_traces[..., 0]
    traces[..., 2:4] = rvo_traces[..., :2]
    traces[..., 4] = np.einsum('...ii->...', cross_speed)
    traces[..., 5] = rvo_traces[..., 2]
    traces[..., 6] = form_traces[..., 1]
    traces[..., 7] = squared_traces[..., 1]
    traces[..., 8::2] = form_traces[..., 2:]
    traces[..., 9::2] = squared_traces[..., 2:]
    return matrices, traces


def rvo_moments_from_forms(forms, traces, combined_radius):
    """
    Assemble ``E[f]`` and ``Var[f]`` from quadratic forms of the mean and traces.

    Parameters
    ----------
    forms : numpy.ndarray
        ``mu'X mu`` for the nine matrices of :func:`rvo_form_matrices`, shape (..., 9).
    traces : numpy.ndarray
        The eight traces of :func:`rvo_form_matrices`, broadcastable to shape (..., 8).
    combined_radius : numpy.ndarray
        ``R``, broadcastable to shape (...).

    Returns
    -------
    expectation, variance : numpy.ndarray
        ``E[f]`` and ``Var[f]``, shape (...).

    """
    radius_sq = np.asarray(combined_radius, dtype=float) ** 2
    k1 = traces[..., 0] + forms[..., 0]
    k2 = 2.0 * traces[..., 1] + 4.0 * forms[..., 1]
    k3 = 8.0 * traces[..., 2] + 24.0 * forms[..., 2]
    k4 = 48.0 * traces[..., 3] + 192.0 * forms[..., 3]
    k_qp = 2.0 * traces[..., 4] + 4.0 * forms[..., 4]
    k_qqp = 8.0 * traces[..., 5] + 16.0 * forms[..., 5] + 8.0 * forms[..., 6]
    mean_p = traces[..., 6] + forms[..., 7]
    var_p = 2.0 * traces[..., 7] + 4.0 * forms[..., 8]
    k1_sq = k1 * k1
    expectation = k2 + k1_sq - radius_sq * mean_p
    variance = (k4 + 4.0 * k3 * k1 + 2.0 * k2 * k2 + 4.0 * k2 * k1_sq
                - 2.0 * radius_sq * (k_qqp + 2.0 * k1 * k_qp) + radius_sq * radius_sq * var_p)
    return expectation, variance


def rvo_moments(mean, cov, radius):
    """
    Exact ``E[f]`` and ``Var[f]`` of ``f = (r x u)^2 - R^2 |u|^2`` for Gaussian ``z = (r, u)``.

    Parameters
    ----------
    mean : array_like
        Mean of ``z = (r_x, r_y, u_x, u_y)``, shape (..., 4).
    cov : array_like
        Covariance of ``z``, shape (..., 4, 4), symmetric PSD (cross terms allowed).
    radius : float or array_like
        Combined radius ``R``, broadcastable to shape (...).

    Returns
    -------
    expectation : numpy.ndarray
        ``E[f]``, shape (...).
    variance : numpy.ndarray
        ``Var[f]``, shape (...).

    """
    mean = np.asarray(mean, dtype=float)
    cov = np.asarray(cov, dtype=float)
    if mean.shape[-1:] != (4,) or cov.shape[-2:] != (4, 4):
        raise ValueError(f'mean must have shape (..., 4) and cov (..., 4, 4), got '
                         f'{mean.shape} and {cov.shape}')
    matrices, traces = form_matrices(cov)
    forms = np.einsum('...i,...kij,...j->...k', mean, matrices[..., :NUM_RVO_FORMS, :, :], mean)
    return rvo_moments_from_forms(forms, traces[..., :8], radius)


def condition_moments(origin, cov, combined_radius, velocities, time_horizon, receding_gate,
                      lead=2.0):
    """
    Mean and variance of every condition at given commanded velocities.

    The conditions are, in order: ``f``; ``g`` if ``receding_gate``; ``h1``, ``h2`` and
    ``h3`` if ``time_horizon`` is finite (docs/method.md, sections 3 and 7).

    Parameters
    ----------
    origin : numpy.ndarray
        Mean of ``z`` at ``v_c = 0``, shape (N, 4).
    cov : numpy.ndarray
        Covariance of ``z``, shape (N, 4, 4).
    combined_radius : numpy.ndarray
        ``R`` per neighbour, shape (N,).
    velocities : numpy.ndarray
        Commanded velocities ``v_c``, shape (P, 2) or (N, P, 2).
    time_horizon : float or numpy.ndarray
        ``tau`` (``inf`` drops ``h1``, ``h2`` and ``h3``), or one per neighbour, shape (N,),
        all finite or all infinite.
    receding_gate : bool
        Whether ``g`` is a condition.
    lead : float or numpy.ndarray
        ``1 / rho``, the factor of the command in the relative velocity, per neighbour,
        shape (N,) (2 for reciprocal avoidance).

    Returns
    -------
    means, variances : numpy.ndarray
        Shape (N, P, C) each.

    """
    finite = np.isfinite(time_horizon).all()
    matrices, traces = form_matrices(
        cov, time_horizon, reach_weights(origin, combined_radius) if finite else None)
    rvo_traces, extra_traces = traces[:, :8], traces[:, 8:]
    # The mean of z at every point, points last: (N, 4, P).
    velocities = np.asarray(velocities, dtype=float)
    mean_t = np.empty((origin.shape[0], 4, velocities.shape[-2]))
    mean_t[:, :2] = origin[:, :2, None]
    mean_t[:, 2:] = origin[:, 2:, None] + np.reshape(lead, (-1, 1, 1)) * velocities.swapaxes(
        -1, -2)
    # mu'X mu as (X mu) . mu with the points last: one (F 4, 4) x (4, P) product per neighbour,
    # contiguous reductions.
    count, forms_count = matrices.shape[:2]
    products = np.matmul(matrices.reshape(count, forms_count * 4, 4), mean_t).reshape(
        count, forms_count, 4, -1)
    products *= mean_t[:, None]
    # The sum over the four components, in the order a reduction over that axis takes.
    forms = products[:, :, 0] + products[:, :, 1]
    forms += products[:, :, 2]
    forms += products[:, :, 3]
    forms = forms.swapaxes(-1, -2)
    f_mean, f_variance = rvo_moments_from_forms(forms[..., :NUM_RVO_FORMS],
                                                rvo_traces[:, None, :], combined_radius[:, None])
    # The quadratic-form conditions (g, h1, h2, h3) from their (mu'X mu, mu'XSX mu) pairs, with g's
    # pair skipped when it is not a condition.
    first = 0 if receding_gate else 2
    extra_forms = forms[..., NUM_RVO_FORMS + first:]
    extra_traces = extra_traces[:, None, first:]
    conditions = 1 + extra_forms.shape[-1] // 2
    means = np.empty(f_mean.shape + (conditions,))
    variances = np.empty(f_mean.shape + (conditions,))
    means[..., 0], variances[..., 0] = f_mean, f_variance
    np.add(extra_traces[..., 0::2], extra_forms[..., 0::2], out=means[..., 1:])
    if finite:
        # h2 = |r + tau u|^2 - R^2, h3 = (1 - eps) (|r|^2 - tau^2 |u|^2 / eps) - R^2.
        means[..., -2:] -= combined_radius[:, None, None] ** 2
    np.multiply(extra_forms[..., 1::2], 4.0, out=variances[..., 1:])
    variances[..., 1:] += 2.0 * extra_traces[..., 1::2]
    return means, variances


def _monomial_exponents():
    """Exponents ``(i, j)`` of ``x^i y^j``, total degree <= 4, grouped by degree."""
    return np.array([(degree - j, j) for degree in range(5) for j in range(degree + 1)])


_EXPONENTS = _monomial_exponents()
# Chebyshev-Lobatto nodes: the 5 x 5 tensor grid is unisolvent for bivariate quartics.
NODES_1D = np.cos(np.pi * np.arange(5) / 4.0)
NODES = np.stack(np.meshgrid(NODES_1D, NODES_1D, indexing='ij'), axis=-1).reshape(-1, 2)
_FIT = np.linalg.pinv(np.prod(NODES[:, None, :] ** _EXPONENTS[None, :, :], axis=-1))
# Total degree of each monomial of _EXPONENTS; the first six have degree <= 2.
_DEGREES = _EXPONENTS.sum(axis=1)
_QUADRATIC_TERMS = 6
# _DEGREE_MASK[k, l]: monomial k contributes to the ray coefficient of t^l, shape (15, 5).
_DEGREE_MASK = (_DEGREES[:, None] == np.arange(5)).astype(float)


def ray_polynomials(origin, cov, combined_radius, directions, scale, time_horizon,
                    receding_gate, lead=2.0):
    """
    Mean and variance polynomials in ``t`` of every condition on every (neighbour, ray) pair.

    Along a ray the commanded velocity is ``v_c = t scale e`` with ``t`` in [0, 1].

    Parameters
    ----------
    origin, cov, combined_radius, time_horizon, receding_gate, lead
        As for :func:`condition_moments`.
    directions : numpy.ndarray
        Unit directions ``e``, shape (M, 2).
    scale : float
        ``v_max``.

    Returns
    -------
    means : numpy.ndarray
        Shape (N, M, C, 3), laid out coefficient-major in memory.
    variances : numpy.ndarray
        Shape (N, M, C, 5), laid out coefficient-major in memory.

    """
    mean_fit, variance_fit = bivariate_polynomials(origin, cov, combined_radius,
                                                   scale * NODES, time_horizon, receding_gate,
                                                   lead)
    count, conditions = mean_fit.shape[:2]
    return tuple(_coefficient_major(rows.reshape(count, conditions, -1, length))
                 for rows, length in zip(ray_rows(mean_fit[None], variance_fit[None],
                                                  directions[None]), (3, 5), strict=True))


def bivariate_polynomials(origin, cov, combined_radius, node_velocities, time_horizon,
                          receding_gate, lead):
    """
    Coefficients of the mean (quadratic) and variance (quartic) of every condition in ``v_c``.

    The coefficients are of the monomials ``(v_x / v_max)^i (v_y / v_max)^j``, fitted on the
    Chebyshev grid ``node_velocities`` = ``v_max`` times the unit grid. Every neighbour's
    coefficients come from its own rows alone, so neighbours of several plans can be stacked.

    Parameters
    ----------
    origin, cov, combined_radius, time_horizon, receding_gate, lead
        As for :func:`condition_moments`.
    node_velocities : numpy.ndarray
        The grid at each neighbour's plan's ``v_max``, shape (25, 2) or (N, 25, 2).

    Returns
    -------
    means : numpy.ndarray
        Shape (N, C, 6).
    variances : numpy.ndarray
        Shape (N, C, 15).

    """
    means, variances = condition_moments(origin, cov, combined_radius, node_velocities,
                                         time_horizon, receding_gate, lead)
    return ((_FIT[:_QUADRATIC_TERMS] @ means).swapaxes(-1, -2),
            (_FIT @ variances).swapaxes(-1, -2))


def ray_rows(mean_fit, variance_fit, directions):
    """
    Restrict bivariate polynomials to rays, for a stack of plans of one shape.

    Parameters
    ----------
    mean_fit, variance_fit : numpy.ndarray
        As :func:`bivariate_polynomials` returns them, per plan: shapes (B, N, C, 6) and
        (B, N, C, 15).
    directions : numpy.ndarray
        Unit directions ``e`` per plan, shape (B, M, 2).

    Returns
    -------
    mean_rows, variance_rows : numpy.ndarray
        Shapes (B, N C, M 3) and (B, N C, M 5): per (neighbour, condition) row, the ascending
        coefficients in ``t`` on each ray. Each plan's are one matrix product of its own.

    """
    # Bivariate coefficient k multiplies t^(i+j) e_x^i e_y^j along the ray: a (15, 5 M) map
    # per plan from bivariate to ray coefficients, applied in one product to every
    # (neighbour, condition).
    robots, rays = directions.shape[:2]
    powers = directions[..., None] ** np.arange(5)
    direction_monomials = (powers[:, :, 0, _EXPONENTS[:, 0]]
                           * powers[:, :, 1, _EXPONENTS[:, 1]])
    to_ray = (direction_monomials.swapaxes(1, 2)[..., None] * _DEGREE_MASK[:, None, :]).reshape(
        robots, _EXPONENTS.shape[0], -1)
    mean_rows = mean_fit.reshape(robots, -1, _QUADRATIC_TERMS) @ to_ray.reshape(
        robots, -1, rays, 5)[:, :_QUADRATIC_TERMS, :, :3].reshape(robots, _QUADRATIC_TERMS, -1)
    variance_rows = variance_fit.reshape(robots, -1, _EXPONENTS.shape[0]) @ to_ray
    return mean_rows, variance_rows


def _coefficient_major(polynomials):
    """
    Lay polynomials of shape (N, C, M, L) out as (L, N, M, C) in memory, viewed as (N, M, C, L).

    Coefficient-major memory suits the ray solver: one coefficient of every row is contiguous.
    """
    layout = np.empty((polynomials.shape[3], polynomials.shape[0], polynomials.shape[2],
                       polynomials.shape[1]))
    layout[...] = polynomials.transpose(3, 0, 2, 1)
    return layout.transpose(1, 2, 3, 0)
