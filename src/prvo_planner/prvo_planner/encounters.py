"""Seeded random encounters for benchmarks, experiments and tests: an ego and its neighbours.

One generator with one distribution type, so that the benchmark, the experiments and the tests
draw their encounters the same way and differ only in the ranges they ask for:

    rng = np.random.default_rng(7)
    ego, neighbours = random_encounter(rng, EncounterDistribution(neighbours=(5, 5)))

The ego stands at the origin; each neighbour is placed at a distance and bearing drawn from
their ranges and moves towards the ego at a drawn speed, plus an optional normal scatter of its
velocity. Every belief has a full random covariance whose standard deviations are drawn from
the position and velocity ranges.
"""

from dataclasses import dataclass
import math

import numpy as np

from prvo_planner.core import AgentBelief


@dataclass(frozen=True)
class EncounterDistribution:
    """The ranges an encounter is drawn from; each pair is (low, high), uniform, inclusive.

    Attributes
    ----------
    neighbours : tuple of int
        How many neighbours.
    distance : tuple of float
        Distance of each neighbour from the ego [m].
    bearing : tuple of float
        Direction of each neighbour as seen from the ego [rad].
    approach_speed : tuple of float
        Speed of each neighbour towards the ego [m/s] (negative: away from it).
    velocity_scatter : float
        Standard deviation of a normal added to each neighbour velocity component [m/s].
    ego_velocity : tuple of float
        Range of each component of the ego's velocity [m/s].
    position_std, velocity_std : tuple of float
        Typical standard deviations of each belief's position [m] and velocity [m/s].
    ego_radius : float
        The ego's radius [m].
    radius : tuple of float
        Each neighbour's radius [m].

    """

    neighbours: tuple = (1, 3)
    distance: tuple = (0.8, 4.0)
    bearing: tuple = (-math.pi, math.pi)
    approach_speed: tuple = (0.0, 1.0)
    velocity_scatter: float = 0.0
    ego_velocity: tuple = (-0.7, 0.7)
    position_std: tuple = (0.02, 0.15)
    velocity_std: tuple = (0.02, 0.15)
    ego_radius: float = 0.3
    radius: tuple = (0.3, 0.3)


def random_covariance(rng, position_std, velocity_std):
    """Return a random full covariance (4, 4) over [x, y, vx, vy], positive definite.

    Its diagonal is of the order of the squared standard deviations given; the correlations
    between all four components are random.
    """
    scales = np.array([position_std, position_std, velocity_std, velocity_std])
    factor = 0.5 * rng.normal(size=(4, 4)) + np.eye(4)
    return scales[:, None] * (factor @ factor.T) * scales[None, :] / 2.0


def _belief(rng, distribution, position, velocity, radius):
    covariance = random_covariance(rng, rng.uniform(*distribution.position_std),
                                   rng.uniform(*distribution.velocity_std))
    return AgentBelief(position, velocity, covariance, radius)


def random_encounter(rng, distribution=EncounterDistribution()):
    """Draw (ego `AgentBelief`, list of neighbour `AgentBelief`s) from DISTRIBUTION with RNG."""
    ego = _belief(rng, distribution, np.zeros(2), rng.uniform(*distribution.ego_velocity, size=2),
                  distribution.ego_radius)
    neighbours = []
    low, high = distribution.neighbours
    for _ in range(int(rng.integers(low, high + 1))):
        bearing = rng.uniform(*distribution.bearing)
        towards_ego = -np.array([math.cos(bearing), math.sin(bearing)])
        position = -rng.uniform(*distribution.distance) * towards_ego
        velocity = (rng.uniform(*distribution.approach_speed) * towards_ego
                    + rng.normal(0.0, distribution.velocity_scatter, size=2))
        neighbours.append(_belief(rng, distribution, position, velocity,
                                  rng.uniform(*distribution.radius)))
    return ego, neighbours
