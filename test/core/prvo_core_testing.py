"""Shared helpers for the core tests: seeded random beliefs and encounters."""

import numpy as np

from prvo_planner.core import AgentBelief


def random_covariance(rng, size, scale):
    """Random full symmetric positive definite matrix with entries of order ``scale**2``."""
    factor = rng.normal(size=(size, size))
    return scale ** 2 * (factor @ factor.T / size + 0.05 * np.eye(size))


def random_two_robot_encounter(rng, position_noise=0.1, velocity_noise=0.1):
    """Ego at the origin heading towards a neighbour 2 to 6 m away, both noisy."""
    distance = rng.uniform(2.0, 6.0)
    bearing = rng.uniform(-0.6, 0.6)
    neighbour_position = distance * np.array([np.cos(bearing), np.sin(bearing)])
    ego = AgentBelief([0.0, 0.0], rng.uniform(-0.2, 1.0, size=2),
                      random_covariance(rng, 4, rng.uniform(0.2, 1.0) * position_noise), 0.3)
    neighbour = AgentBelief(neighbour_position,
                            -0.8 * neighbour_position / distance + rng.normal(0.0, 0.3, size=2),
                            random_covariance(rng, 4, rng.uniform(0.2, 1.0) * velocity_noise),
                            rng.uniform(0.2, 0.5))
    return ego, neighbour
