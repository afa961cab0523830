"""Cantelli's bound and Monte Carlo estimates of the RVO condition."""

import math

import numpy as np

from .beliefs import as_covariance, as_finite_array

# From this k on, 1 + k^2 rounds to k^2 (k^2 > 2^53), so k^2 / (1 + k^2) is exactly 1; beyond
# 1.3e154 k^2 overflows and the quotient would be inf / inf (``wall_kernels.cantelli_bounds``
# has its own copy).
_CERTAIN_K = 1e8


def eta_from_k(k):
    """
    Cantelli lower bound on ``P(f >= 0)`` when ``mu_f - k sigma_f >= 0``.

    Parameters
    ----------
    k : float or array_like
        Margin, >= 0; ``inf`` gives 1.

    Returns
    -------
    float or numpy.ndarray
        ``k^2 / (1 + k^2)``.

    """
    if isinstance(k, float):
        # Scalars without numpy: the planner converts a margin on every call.
        if not k >= 0.0:
            raise ValueError(f'k must be >= 0, got {k!r}')
        return 1.0 if k >= _CERTAIN_K else k * k / (1.0 + k * k)
    return _cantelli(k, False)


def cantelli_of_margins(margins):
    """
    Cantelli's bound of ``max(k, 0)`` for each margin: :func:`eta_from_k` of the clipped margins.

    Parameters
    ----------
    margins : array_like
        Margins ``k`` (negative ones are taken as 0), any shape.

    Returns
    -------
    numpy.ndarray
        The bounds, the shape of ``margins``.

    """
    return _cantelli(margins, True)


def _cantelli(k, clipped):
    """Cantelli's bound of an array (compiled: :func:`.wall_kernels.cantelli_bounds`)."""
    from .wall_kernels import cantelli_bounds
    k = np.asarray(k, dtype=float)
    bounds, valid = cantelli_bounds(np.ascontiguousarray(k.reshape(-1)), clipped)
    if not valid:
        raise ValueError(f'k must be >= 0, got {k.tolist()!r}')
    return float(bounds[0]) if k.ndim == 0 else bounds.reshape(k.shape)


def k_from_eta(eta):
    """
    Smallest margin ``k`` whose Cantelli bound is ``eta``.

    Parameters
    ----------
    eta : float or array_like
        Probability in [0, 1).

    Returns
    -------
    float or numpy.ndarray
        ``sqrt(eta / (1 - eta))``.

    """
    if isinstance(eta, float):
        if not 0.0 <= eta < 1.0:
            raise ValueError(f'eta must be in [0, 1), got {eta!r}')
        return math.sqrt(eta / (1.0 - eta))
    eta = np.asarray(eta, dtype=float)
    if np.any(np.isnan(eta)) or np.any(eta < 0.0) or np.any(eta >= 1.0):
        raise ValueError(f'eta must be in [0, 1), got {eta.tolist()!r}')
    k = np.sqrt(eta / (1.0 - eta))
    return float(k) if k.ndim == 0 else k


def confidence_ellipse_scale(k):
    """
    Scale ``c`` of the ``eta`` confidence ellipse of a 2D Gaussian, with ``eta`` given by ``k``.

    The ellipse ``x' S^-1 x <= c^2`` holds probability ``eta = 1 - exp(-c^2 / 2)``, so
    ``c = sqrt(-2 ln(1 - eta))``; with Cantelli's ``eta = k^2 / (1 + k^2)`` that is
    ``sqrt(2 ln(1 + k^2))``, computed from ``k`` so that it stays finite as ``eta -> 1``.

    Parameters
    ----------
    k : float
        Margin, >= 0.

    Returns
    -------
    float
        ``c``; the radius-enlargement baseline grows ``R`` by ``c sqrt(lambda_max)``.

    """
    return math.sqrt(2.0 * math.log1p(k * k))


def sample_relative_states(ego, neighbour, command, actuation_cov, n_samples, rng):
    """
    Sample ``z = (r, w)`` for one pair by sampling both beliefs and the actuation noise.

    ``w`` is the relative velocity at the neighbour's share of the avoidance (``u`` at 1/2).

    Parameters
    ----------
    ego, neighbour : AgentBelief
        The two beliefs (independent of each other).
    command : numpy.ndarray
        Commanded ego velocity ``v_c``, shape (2,).
    actuation_cov : numpy.ndarray
        ``S_a``, shape (2, 2).
    n_samples : int
        Number of samples.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    numpy.ndarray
        Samples of ``z``, shape (n_samples, 4).

    """
    ego_state = rng.multivariate_normal(np.r_[ego.position, ego.velocity], ego.covariance,
                                        size=n_samples, method='eigh')
    neighbour_state = rng.multivariate_normal(np.r_[neighbour.position, neighbour.velocity],
                                              neighbour.covariance, size=n_samples,
                                              method='eigh')
    noise = rng.multivariate_normal(np.zeros(2), actuation_cov, size=n_samples, method='eigh')
    relative_position = ego_state[:, :2] - neighbour_state[:, :2]
    # w of docs/method.md, section 11: at the neighbour's share 1/2, u = 2 v_x - v_i - v_j.
    rho = 1.0 - neighbour.avoidance_share
    relative_velocity = ((command + noise) / rho - ((1.0 - rho) / rho) * ego_state[:, 2:]
                         - neighbour_state[:, 2:])
    return np.concatenate([relative_position, relative_velocity], axis=1)


def rvo_condition(z, combined_radius):
    """
    Evaluate ``f(r, u) = (r x u)^2 - R^2 |u|^2`` (docs/method.md, section 3).

    Parameters
    ----------
    z : numpy.ndarray
        Relative states ``(r_x, r_y, u_x, u_y)``, shape (..., 4).
    combined_radius : float or numpy.ndarray
        ``R``, broadcastable to shape (...).

    Returns
    -------
    numpy.ndarray
        ``f``, shape (...).

    """
    return rvo_condition_of(z[..., 0], z[..., 1], z[..., 2], z[..., 3], combined_radius)


def rvo_condition_of(r_x, r_y, u_x, u_y, combined_radius):
    """``f`` of :func:`rvo_condition` from broadcastable components (no stacked ``z``)."""
    cross = r_x * u_y - r_y * u_x
    return cross * cross - combined_radius ** 2 * (u_x * u_x + u_y * u_y)


def rvo_satisfaction_probability(ego, neighbour, command, actuation_cov, n_samples=100_000,
                                 rng=None):
    """
    Monte Carlo estimate of ``P(f >= 0)`` at a commanded velocity.

    Samples the ego belief, the neighbour belief and the actuation noise independently, with
    ``R`` the sum of the two radii.

    Parameters
    ----------
    ego, neighbour : AgentBelief
        The two beliefs.
    command : array_like
        Commanded ego velocity ``v_c``, shape (2,).
    actuation_cov : array_like
        ``S_a``, shape (2, 2).
    n_samples : int
        Number of samples.
    rng : numpy.random.Generator or int or None
        Passed to ``np.random.default_rng``.

    Returns
    -------
    float
        Fraction of samples with ``f >= 0``.

    """
    rng = np.random.default_rng(rng)
    command = as_finite_array(command, (2,), 'command')
    actuation_cov = as_covariance(actuation_cov, 2, 'actuation_cov')
    if int(n_samples) < 1:
        raise ValueError(f'n_samples must be >= 1, got {n_samples!r}')
    z = sample_relative_states(ego, neighbour, command, actuation_cov, int(n_samples), rng)
    return float(np.mean(rvo_condition(z, ego.radius + neighbour.radius) >= 0.0))
