"""The reach condition h3: a robot too slow to reach a neighbour within the horizon is safe.

``h3 = (1 - eps) (|r|^2 - tau^2 |w|^2 / eps) - R^2 >= 0`` (docs/method.md, section 7) implies
that the segment ``r + t w``, ``t`` in ``[0, tau]``, keeps ``R`` from the origin: checked on
sampled segments against their own closest points. Planned with it, a robot in front of
neighbours that stand (announcing no share, their velocity estimates noisy) may stand and creep
toward them, as safe as it states by sampling; without it, standing still was no plan there
(the closest approach of a relative velocity near zero may be at any time).
"""

from independent import gaussian
import numpy as np
import pytest

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.core.moments import reach_weights

SAMPLES = 4000
# One-sided z for a family-wise false alarm below 1e-3 over the checks of this module.
Z = 4.5
NOISE = np.diag([0.015 ** 2] * 2 + [0.048 ** 2] * 2)


def h3(r, w, radius, tau, weight):
    """``h3`` of relative positions R (..., 2) and velocities W (..., 2), by its definition."""
    return ((1.0 - weight) * (np.sum(r * r, axis=-1) - tau ** 2 * np.sum(w * w, axis=-1) / weight)
            - radius ** 2)


def closest_on_horizon(r, w, tau):
    """Return the least ``|r + t w|`` over ``t`` in ``[0, tau]``, shape (...)."""
    speed_sq = np.sum(w * w, axis=-1)
    t = np.clip(-np.sum(r * w, axis=-1) / np.maximum(speed_sq, 1e-300), 0.0, tau)
    return np.hypot(*np.moveaxis(r + t[..., None] * w, -1, 0))


def test_the_reach_condition_keeps_the_whole_horizon_clear():
    rng = np.random.default_rng(53)
    count = 200_000
    r = rng.uniform(-6.0, 6.0, (count, 2))
    w = rng.normal(0.0, 0.6, (count, 2))
    radius, tau = rng.uniform(0.2, 1.2, count), rng.uniform(0.5, 6.0, count)
    weight = rng.uniform(0.05, 0.95, count)
    held = h3(r, w, radius, tau, weight) >= 0.0
    assert held.sum() > 10_000
    assert np.all(closest_on_horizon(r[held], w[held], tau[held]) >= radius[held] - 1e-12)


def test_at_the_mean_distance_the_reach_condition_is_exact_head_on():
    # Straight at the neighbour from its mean distance d, with the weight of d: h3 holds
    # exactly while the robot cannot cover d - R within the horizon.
    radius, tau = 0.5, 4.0
    origin = np.array([[3.0, 0.0, 0.0, 0.0]])
    (weight,) = reach_weights(origin, np.array([radius]))
    assert weight == pytest.approx(1.0 - radius / 3.0)
    limit = (3.0 - radius) / tau
    speeds = limit * np.array([0.999, 1.001])
    values = h3(np.array([3.0, 0.0]), -speeds[:, None] * np.array([1.0, 0.0]), radius, tau,
                weight)
    assert values[0] > 0.0 > values[1]


def standing_samples(rng, ego, neighbour, command, actuation):
    """Sample (r, w), each (SAMPLES, 2), against a neighbour taking no share, at COMMAND.

    r = p_ego - p_neighbour; w = v_c + a - v_neighbour with a ~ N(0, S_a): the ego takes the
    whole avoidance, and its own velocity estimate does not enter.
    """
    own = gaussian(rng, np.r_[ego.position, ego.velocity], ego.covariance, SAMPLES)
    other = gaussian(rng, np.r_[neighbour.position, neighbour.velocity], neighbour.covariance,
                     SAMPLES)
    executed = command + gaussian(rng, np.zeros(2), actuation, SAMPLES)
    return own[:, :2] - other[:, :2], executed - other[:, 2:]


def standing_pair(rng):
    """Ego at the origin, standing, and two neighbours 1.5-4 m ahead standing at their goals."""
    ego = AgentBelief([0.0, 0.0], rng.normal(0.0, 0.05, 2), NOISE, 0.25)
    neighbours = []
    for _ in range(2):
        bearing, distance = rng.uniform(-0.5, 0.5), rng.uniform(1.5, 4.0)
        neighbours.append(AgentBelief(distance * np.array([np.cos(bearing), np.sin(bearing)]),
                                      rng.normal(0.0, 0.05, 2), NOISE, 0.25, 0.0))
    return ego, neighbours


@pytest.mark.parametrize('certificate, eta', [('cantelli', 0.8), ('certified', 0.95)])
def test_a_robot_may_stand_and_creep_in_front_of_standing_neighbours(certificate, eta):
    rng, sampler = np.random.default_rng(7), np.random.default_rng(8)
    actuation = 0.05 ** 2 * np.eye(2)
    config = PlannerConfig(eta=eta, certificate=certificate, time_horizon=4.6,
                           actuation_cov=actuation)
    standing = creeping = 0
    for _ in range(30):
        ego, neighbours = standing_pair(rng)
        for v_pref in ((0.0, 0.0), (0.15, 0.0)):
            result = plan_velocity(ego, neighbours, np.array(v_pref), config)
            assert result.feasible
            if np.allclose(result.velocity, v_pref, atol=1e-9):
                standing += v_pref == (0.0, 0.0)
                creeping += v_pref != (0.0, 0.0)
            for neighbour in neighbours:
                position, velocity = standing_samples(sampler, ego, neighbour,
                                                      result.velocity, actuation)
                # Safe: never closer than the sum of radii, or than the robots already are.
                safe = closest_on_horizon(position, velocity, config.time_horizon) >= np.minimum(
                    ego.radius + neighbour.radius, np.hypot(*position.T)) - 1e-12
                assert safe.mean() >= eta - Z * np.sqrt(eta * (1.0 - eta) / SAMPLES)
    # Standing still is a plan in nearly every encounter, and creeping ahead in most (under
    # Cantelli's bound, without h3: in none, and in one).
    assert standing >= 27 and creeping >= 18
