"""Ground truth for the core tests, written without the package's own helpers.

The guarantees are checked against these, not against `prvo_planner.core.probability`: a
sampler built from standard normals and each belief's own square root, and the RVO condition
by its geometric meaning (the line of relative motion keeps its distance from the other robot)
instead of the polynomial `f` the planner works with.
"""

import numpy as np


def square_root(covariance):
    """Return L with L L^T = COVARIANCE for a positive semi-definite matrix (zero allowed)."""
    values, vectors = np.linalg.eigh(np.asarray(covariance, dtype=float))
    return vectors * np.sqrt(np.clip(values, 0.0, None))


def gaussian(rng, mean, covariance, count):
    """Draw COUNT samples (count, n) of N(MEAN, COVARIANCE) from standard normals."""
    mean = np.asarray(mean, dtype=float)
    return mean + rng.standard_normal((count, mean.size)) @ square_root(covariance).T


def relative_samples(rng, ego, neighbour, command, actuation_cov, count):
    """Sample (r, u), each (count, 2), of a reciprocating pair at the ego's COMMAND.

    r = p_ego - p_neighbour; u = 2 (v_c + a) - v_ego - v_neighbour, with a ~ N(0, S_a): both
    robots take half of the avoidance, each measured with its own belief's error.
    """
    ego_state = gaussian(rng, np.r_[ego.position, ego.velocity], ego.covariance, count)
    other = gaussian(rng, np.r_[neighbour.position, neighbour.velocity], neighbour.covariance,
                     count)
    executed = np.asarray(command, dtype=float) + gaussian(rng, np.zeros(2), actuation_cov, count)
    return (ego_state[:, :2] - other[:, :2],
            2.0 * executed - ego_state[:, 2:] - other[:, 2:])


def line_clear(r, u, radius):
    """Whether the line r + t u (all real t) stays at least RADIUS from the origin.

    The closest point is the projection t* = -(r . u) / |u|^2; a relative velocity of zero
    (no relative motion) counts as clear, as the planner's condition does.
    """
    r, u = np.asarray(r, dtype=float), np.asarray(u, dtype=float)
    speed_sq = np.sum(u * u, axis=-1)
    moving = speed_sq > 0.0
    t = -np.sum(r * u, axis=-1) / np.where(moving, speed_sq, 1.0)
    closest_sq = np.sum((r + t[..., None] * u) ** 2, axis=-1)
    return ~moving | (closest_sq >= radius ** 2)


def rvo_f(r, u, radius):
    """Return the RVO condition's polynomial f = (r x u)^2 - R^2 |u|^2, written out."""
    r, u = np.asarray(r, dtype=float), np.asarray(u, dtype=float)
    cross = r[..., 0] * u[..., 1] - r[..., 1] * u[..., 0]
    return cross ** 2 - radius ** 2 * np.sum(u * u, axis=-1)
