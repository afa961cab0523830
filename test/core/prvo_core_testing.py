"""Shared helpers for the core tests: seeded random beliefs and encounters."""

import numpy as np

from prvo_planner.core import AgentBelief
from prvo_planner.core.encounter import build_encounter, candidate_directions, condition_layout
from prvo_planner.core.moments import ray_polynomials
from prvo_planner.encounters import EncounterDistribution, random_encounter


def random_covariance(rng, size, scale):
    """Random full symmetric positive definite matrix with entries of order ``scale**2``."""
    factor = rng.normal(size=(size, size))
    return scale ** 2 * (factor @ factor.T / size + 0.05 * np.eye(size))


def random_two_robot_encounter(rng, position_noise=0.1, velocity_noise=0.1):
    """Ego at the origin heading towards a neighbour 2 to 6 m away, both noisy."""
    ego, (neighbour,) = random_encounter(rng, EncounterDistribution(
        neighbours=(1, 1), distance=(2.0, 6.0), bearing=(-0.6, 0.6), approach_speed=(0.8, 0.8),
        velocity_scatter=0.3, ego_velocity=(-0.2, 1.0),
        position_std=(0.2 * position_noise, position_noise),
        velocity_std=(0.2 * velocity_noise, velocity_noise), radius=(0.2, 0.5)))
    return ego, neighbour


def crowd(rng, count, noise):
    """Ego at the origin and ``count`` neighbours in a 10 m box, none overlapping the ego."""
    ego = AgentBelief([0.0, 0.0], rng.uniform(-0.5, 1.0, size=2),
                      random_covariance(rng, 4, noise) if noise else np.zeros((4, 4)), 0.3)
    neighbours = []
    while len(neighbours) < count:
        position = rng.uniform(-5.0, 5.0, size=2)
        if np.hypot(*position) > 1.0:
            neighbours.append(AgentBelief(
                position, rng.uniform(-1.0, 1.0, size=2),
                random_covariance(rng, 4, noise) if noise else np.zeros((4, 4)), 0.3))
    return ego, neighbours


def crowd_rays(ego, neighbours, config):
    """Return (encounter, layout, directions (M', 2), means, variances) of a plan's rays.

    The candidate directions are those of a preference along +x; the ray polynomials are
    `ray_polynomials`' over them, at CONFIG's speed and horizon.
    """
    encounter = build_encounter(ego, neighbours, config)
    layout = condition_layout(encounter, config)
    directions = candidate_directions(ego, np.array([1.0, 0.0]), config)
    means, variances = ray_polynomials(encounter.origin, encounter.cov, encounter.combined_radius,
                                       directions, config.max_speed, config.time_horizon,
                                       layout.has_receding)
    return encounter, layout, directions, means, variances
