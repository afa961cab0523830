"""A Monte Carlo check of a run's plans, with a sampler of its own (the rules' runs share it).

Each plan of a robot with a neighbour within ENCOUNTER is sampled: relative position and velocity
from the beliefs it planned with and the actuation noise, and the share of executions that stay
safe within the horizon is compared with the probability the plan states.
"""

import math

import numpy as np

SAMPLES = 4000
# Neighbours nearer than this [m] make a plan an encounter's.
ENCOUNTER = 3.0


def gaussian(rng, mean, covariance, count):
    """Draw COUNT samples (count, n) of N(MEAN, COVARIANCE) from standard normals."""
    values, vectors = np.linalg.eigh(covariance)
    root = vectors * np.sqrt(np.clip(values, 0.0, None))
    return np.asarray(mean) + rng.standard_normal((count, len(mean))) @ root.T


def safe_share(rng, ego, neighbour, command, config):
    """Return the sampled share of executions safe within the horizon, as the planner states it.

    Relative position r and velocity u sampled from the beliefs and the actuation noise, the
    ego taking the share of the avoidance its neighbour leaves it: u = (executed - v_ego) /
    (1 - s) + v_ego - v_neighbour for a neighbour announcing share s (2 executed - v_ego -
    v_neighbour for a reciprocating one, executed - v_neighbour for one standing at its goal);
    safe: on [0, horizon] the robots come no closer than the sum of radii, or than they
    already are.
    """
    own = gaussian(rng, np.r_[ego.position, ego.velocity], ego.covariance, SAMPLES)
    other = gaussian(rng, np.r_[neighbour.position, neighbour.velocity], neighbour.covariance,
                     SAMPLES)
    executed = command + gaussian(rng, np.zeros(2), config.actuation_cov, SAMPLES)
    r = own[:, :2] - other[:, :2]
    share = neighbour.avoidance_share
    u = (executed - own[:, 2:]) / (1.0 - share) + own[:, 2:] - other[:, 2:]
    closest = np.clip(-np.sum(r * u, axis=1) / np.maximum(np.sum(u * u, axis=1), 1e-300),
                      0.0, config.time_horizon)
    distance_sq = np.sum((r + closest[:, None] * u) ** 2, axis=1)
    radius = ego.radius + neighbour.radius + config.safety_margin
    return np.mean(distance_sq >= np.minimum(radius ** 2, np.sum(r * r, axis=1)) - 1e-12)


class EncounterChecker:
    """Collects the sampled safe share of every encounter plan of a run (`check` per step)."""

    def __init__(self, rng):
        self.rng = rng
        self.checked = []

    def check(self, team, positions):
        """Sample the plans of TEAM's last step (an `InProcessTeam`; POSITIONS unused)."""
        for request, command in zip(team.last_requests, team.last_commands, strict=True):
            if request.problem is None or not command.result.feasible:
                continue
            ego, neighbours, _, config = request.problem[:4]
            for neighbour in neighbours:
                if np.hypot(*(neighbour.position - ego.position)) > ENCOUNTER:
                    continue
                self.checked.append((safe_share(self.rng, ego, neighbour, command.velocity,
                                                config), config.effective_eta))

    def assert_safe(self, at_least):
        """Assert AT_LEAST plans were sampled, each safe with its eta within 4 binomial stds."""
        shares, etas = np.array(self.checked).T
        assert len(shares) >= at_least
        tolerance = 4.0 * np.sqrt(etas * (1.0 - etas) / SAMPLES)
        assert (shares >= etas - tolerance).all(), (shares - etas).min()
        assert math.isclose(etas.min(), 0.95)
