"""The guarantee carries over to a differential-drive robot that tracks its plan.

A unicycle plans a holonomic velocity among those it can track within `E`, with its radius grown
by `E`, and drives it with the tracking controller. Over the planner's own beliefs (sampled
here, independently of the planner's moments), the executed path must stay clear of each
neighbour over the horizon with at least the probability the plan reports (its eta bound).
"""

import math

import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, VelocityLimits, plan_velocity
from prvo_planner.tracking import TrackingModel, tracking_command

RADIUS = 0.3
TRACKING_ERROR = 0.1
PERIOD = 0.1
HORIZON = 5.0
SAMPLES = 4000
ENCOUNTERS = 12


def random_covariance(rng, position_std, velocity_std):
    """Return a positive definite (4, 4) covariance with position-velocity cross terms."""
    scales = np.array([position_std, position_std, velocity_std, velocity_std])
    correlation = np.eye(4)
    correlation[0, 2] = correlation[2, 0] = rng.uniform(-0.5, 0.5)
    correlation[1, 3] = correlation[3, 1] = rng.uniform(-0.5, 0.5)
    return correlation * np.outer(scales, scales)


def encounter(seed):
    """Return an ego unicycle with a random heading and 1 to 3 neighbours coming near."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-math.pi, math.pi)
    heading = np.array([math.cos(yaw), math.sin(yaw)])
    ego = AgentBelief([0.0, 0.0], rng.uniform(0.0, 0.8) * heading,
                      random_covariance(rng, 0.05, 0.05), RADIUS + TRACKING_ERROR)
    neighbours = []
    for _ in range(rng.integers(1, 4)):
        bearing = rng.uniform(-math.pi, math.pi)
        distance = rng.uniform(1.5, 4.0)
        position = distance * np.array([math.cos(bearing), math.sin(bearing)])
        velocity = -position / distance * rng.uniform(0.3, 1.0) + rng.normal(0.0, 0.2, 2)
        neighbours.append(AgentBelief(position, velocity, random_covariance(rng, 0.05, 0.08),
                                      RADIUS))
    goal_bearing = rng.uniform(-math.pi, math.pi)
    v_pref = np.array([math.cos(goal_bearing), math.sin(goal_bearing)])
    return yaw, ego, neighbours, v_pref


def executed_offsets(velocity, yaw, model, times):
    """Offsets from the straight path of the unicycle driving VELOCITY from YAW at TIMES.

    Small Euler steps of the held commands: independent of the planner's tracking table.
    """
    substeps = 50
    position, heading, forward, turn = np.zeros(2), yaw, 0.0, 0.0
    offsets = np.zeros((times.size, 2))
    index = 1
    for step in range(round(times[-1] / PERIOD)):
        forward, turn = tracking_command(velocity, heading, forward, turn, model, PERIOD)
        for substep in range(substeps):
            position = position + forward * np.array([math.cos(heading), math.sin(heading)]) \
                * (PERIOD / substeps)
            heading += turn * PERIOD / substeps
            now = step * PERIOD + (substep + 1) * PERIOD / substeps
            if index < times.size and now >= times[index] - 1e-12:
                offsets[index] = position - now * velocity
                index += 1
    return offsets


def clear_probability(ego, neighbour, velocity, actuation_cov, offsets, times, rng):
    """Fraction of samples of the beliefs in which the executed path keeps clear until tau.

    The neighbour takes its reciprocal half, as the planner assumes: the relative position is
    r + t (2 v_x - v_i - v_j) plus the ego's tracking offset.
    """
    ego_samples = rng.multivariate_normal(np.concatenate([ego.position, ego.velocity]),
                                          ego.covariance, SAMPLES)
    other = rng.multivariate_normal(np.concatenate([neighbour.position, neighbour.velocity]),
                                    neighbour.covariance, SAMPLES)
    executed = velocity + rng.multivariate_normal(np.zeros(2), actuation_cov, SAMPLES)
    relative = ego_samples[:, :2] - other[:, :2]
    relative_velocity = 2.0 * executed - ego_samples[:, 2:] - other[:, 2:]
    paths = (relative[:, None, :] + times[None, :, None] * relative_velocity[:, None, :]
             + offsets[None, :, :])
    clearance = np.min(np.linalg.norm(paths, axis=2), axis=1)
    return float(np.mean(clearance >= RADIUS + neighbour.radius))


def test_executed_unicycle_motion_keeps_the_reported_bound():
    model = TrackingModel(1.0, 2.0, math.inf, math.inf, 0.5, TRACKING_ERROR)
    config = PlannerConfig(eta=0.8, actuation_cov=0.0025 * np.eye(2), time_horizon=HORIZON,
                           inertia=0.5, passing_bias=0.1)
    rng = np.random.default_rng(2024)
    times = np.linspace(0.0, HORIZON, 501)
    checked, largest_offset = 0, 0.0
    for seed in range(ENCOUNTERS):
        yaw, ego, neighbours, v_pref = encounter(seed)
        limits = VelocityLimits(heading=yaw, trackable_speed=model.speed_function(PERIOD))
        result = plan_velocity(ego, neighbours, v_pref, config, limits=limits)
        if not result.feasible:
            continue
        offsets = executed_offsets(result.velocity, yaw, model, times)
        largest_offset = max(largest_offset, float(np.max(np.linalg.norm(offsets, axis=1))))
        # The executed path stays within E of the planned one.
        assert np.max(np.linalg.norm(offsets, axis=1)) <= TRACKING_ERROR * (1.0 + 1e-3), seed
        for neighbour in neighbours:
            probability = clear_probability(ego, neighbour, result.velocity,
                                            config.actuation_cov, offsets, times, rng)
            # Four standard errors of the estimate below the bound would be a failure.
            slack = 4.0 * math.sqrt(result.eta_bound * (1.0 - result.eta_bound) / SAMPLES)
            assert probability >= result.eta_bound - slack, (seed, probability,
                                                             result.eta_bound)
        checked += 1
    assert checked >= ENCOUNTERS // 2
    # The encounters do make the robot turn: its path is not the planned line.
    assert largest_offset > 0.5 * TRACKING_ERROR


def test_with_exact_beliefs_the_grown_radius_is_what_keeps_the_unicycle_clear():
    """Noise-free, the plan grazes the grown disc: the tracked path keeps the true radii.

    Planned with the plain radius instead, the tracked path cuts into some neighbour: the growth
    by E is what carries the guarantee over.
    """
    model = TrackingModel(1.0, 2.0, math.inf, math.inf, 0.5, TRACKING_ERROR)
    config = PlannerConfig(eta=0.8, model='rvo', time_horizon=HORIZON)
    times = np.linspace(0.0, HORIZON, 501)
    exact = 1e-12 * np.eye(4)
    worst = {}
    for growth in (TRACKING_ERROR, 0.0):
        clearances = []
        for seed in range(40):
            yaw, ego, neighbours, v_pref = encounter(seed)
            ego = AgentBelief(ego.position, ego.velocity, exact, RADIUS + growth)
            neighbours = [AgentBelief(other.position, other.velocity, exact, RADIUS)
                          for other in neighbours]
            result = plan_velocity(ego, neighbours, v_pref, config, limits=VelocityLimits(
                heading=yaw, trackable_speed=model.speed_function(PERIOD)))
            assert result.feasible, seed
            offsets = executed_offsets(result.velocity, yaw, model, times)
            for other in neighbours:
                relative_velocity = 2.0 * result.velocity - ego.velocity - other.velocity
                paths = (ego.position - other.position + times[:, None] * relative_velocity
                         + offsets)
                clearances.append(np.min(np.linalg.norm(paths, axis=1)) - 2.0 * RADIUS)
        worst[growth] = min(clearances)
    assert worst[TRACKING_ERROR] >= 0.0
    assert worst[0.0] < 0.0
