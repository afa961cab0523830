"""The fallback near contact: exactly symmetric head-on pairs and trapped robots, by geometry."""

import dataclasses
import math

import numpy as np
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import AgentBelief, PlannerConfig, VelocityLimits, plan_velocity

RADIUS = 0.3
MAX_SPEED = 1.0
# The core's default control period: how long each command below stays in force.
PERIOD = 0.1


@dataclasses.dataclass(frozen=True)
class OwnMeasurement:
    """The fields of an odometry measurement the agent reads."""

    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0


def rotation(degrees):
    """Rotation matrix by DEGREES, shape (2, 2)."""
    cosine, sine = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[cosine, -sine], [sine, cosine]])


def pushed_head_on(gap, overlap, push_speed):
    """
    Return a standing head-on pair, each robot pushed from behind by an overlapping one.

    The pair stands on the x axis GAP apart (between surfaces); each pusher overlaps its robot
    by OVERLAP and drives on at PUSH_SPEED. Positions, velocities and goals of the four, each
    shape (4, 2): symmetric under a half turn, the pair's goals beyond each other, the
    pushers' straight ahead.
    """
    half = RADIUS + 0.5 * gap
    behind = half + 2.0 * RADIUS - overlap
    positions = np.array([[-half, 0.0], [half, 0.0], [-behind, 0.0], [behind, 0.0]])
    velocities = np.array([[0.0, 0.0], [0.0, 0.0], [push_speed, 0.0], [-push_speed, 0.0]])
    goals = np.array([[5.0, 0.0], [-5.0, 0.0], [5.0, 0.0], [-5.0, 0.0]])
    return positions, velocities, goals


@pytest.mark.parametrize(('gap', 'overlap', 'push_speed'),
                         [(0.005, 0.002, 0.2), (0.02, 0.002, 0.5), (0.05, 0.002, 1.0)])
def test_symmetric_head_on_pair_does_not_step_into_each_other(gap, overlap, push_speed):
    # Every robot plans (noise-free RVO, the crowd settings); the pair has no feasible
    # velocity. Receding from its pusher leads each towards the other, a hair away: they must
    # not close that gap over the period. Where all four will be is computed here by hand.
    positions, velocities, goals = pushed_head_on(gap, overlap, push_speed)
    config = PlannerConfig(model='rvo', max_speed=MAX_SPEED, inertia=0.5, passing_bias=0.1,
                           progress_weight=0.5)
    beliefs = [AgentBelief(position, velocity, np.zeros((4, 4)), RADIUS)
               for position, velocity in zip(positions, velocities, strict=True)]
    results = []
    for index, ego in enumerate(beliefs):
        heading = goals[index] - positions[index]
        results.append(plan_velocity(ego, beliefs[:index] + beliefs[index + 1:],
                                     MAX_SPEED * heading / np.linalg.norm(heading), config,
                                     previous=velocities[index]))
    assert [result.candidates_feasible for result in results[:2]] == [0, 0]
    later = positions + PERIOD * np.array([result.velocity for result in results])
    separation = math.hypot(*(later[0] - later[1])) - 2.0 * RADIUS
    assert separation >= 0.0, (separation, results[0].velocity, results[1].velocity)


@pytest.mark.parametrize('degrees', [0.0, 45.0, 135.0, 270.0])
def test_symmetric_head_on_mirror_ties_pass_on_the_right(degrees):
    # Two robots head on at 1 m/s that can change their command by 0.5 m/s only (acceleration
    # limit): nothing is feasible. Without passing bias the two sides of each one's preferred
    # direction cost the same; both must take the side that passes the other on the right,
    # whichever way the scene is turned (r x u > 0, r from the second to the first, u the
    # first's velocity relative to the second's). Their commands mirror each other.
    turn = rotation(degrees)
    half = RADIUS + 0.4
    first = AgentBelief(turn @ [-half, 0.0], turn @ [MAX_SPEED, 0.0], np.zeros((4, 4)), RADIUS)
    second = AgentBelief(turn @ [half, 0.0], turn @ [-MAX_SPEED, 0.0], np.zeros((4, 4)), RADIUS)
    config = PlannerConfig(model='rvo', max_speed=MAX_SPEED, num_directions=16,
                           time_horizon=2.0, passing_bias=0.0, inertia=0.0)
    results = [plan_velocity(ego, [other], MAX_SPEED * (other.position - ego.position) / (
        2.0 * half), config, limits=VelocityLimits(current=ego.velocity, max_change=0.5))
        for ego, other in ((first, second), (second, first))]
    assert [result.candidates_feasible for result in results] == [0, 0]
    offset = first.position - second.position
    relative = results[0].velocity - results[1].velocity
    # Sideways: a tie between mirror images exists only off the axis.
    assert abs(offset[0] * relative[1] - offset[1] * relative[0]) > 1e-3
    assert offset[0] * relative[1] - offset[1] * relative[0] > 0.0
    np.testing.assert_allclose(results[0].velocity, -results[1].velocity, atol=1e-9)


def trapped_near_encounter(rng):
    """
    Ego at the origin, one neighbour just short of touching it, a closing ring around them.

    Exactly known beliefs (zero covariance). The near neighbour drifts slowly, so that moving
    straight away from it recedes; the ring is dense enough that nothing is feasible.
    """
    ego = AgentBelief([0.0, 0.0], rng.uniform(-0.3, 0.3, size=2), np.zeros((4, 4)), RADIUS)
    bearing = rng.uniform(0.0, 2.0 * math.pi)
    toward = np.array([math.cos(bearing), math.sin(bearing)])
    near = AgentBelief((2.0 * RADIUS + rng.uniform(0.002, 0.05)) * toward,
                       rng.uniform(-0.1, 0.1, size=2), np.zeros((4, 4)), RADIUS)
    neighbours = [near]
    count = int(rng.integers(5, 9))
    for index in range(count):
        angle = bearing + 2.0 * math.pi * (index + rng.uniform(0.3, 0.7)) / count
        direction = np.array([math.cos(angle), math.sin(angle)])
        neighbours.append(AgentBelief(rng.uniform(0.75, 1.3) * direction,
                                      -rng.uniform(0.2, 0.8) * direction, np.zeros((4, 4)),
                                      RADIUS))
    # The goal lies beyond the near neighbour: the cheapest commands close on it.
    return ego, neighbours, toward * rng.uniform(0.5, 1.0)


def closing_speed(ego, neighbour, velocity):
    """How fast the centres' distance shrinks at command VELOCITY (reciprocal), m/s (>= 0)."""
    offset = ego.position - neighbour.position
    relative = 2.0 * np.asarray(velocity) - ego.velocity - neighbour.velocity
    step = 1e-6
    later = np.linalg.norm(offset + step * relative, axis=-1)
    return np.maximum(math.hypot(*offset) - later, 0.0) / step


def within_one_period(ego, neighbour):
    """Whether some command could bring NEIGHBOUR into contact within one control period."""
    # Reciprocal relative velocity 2 v - v_i - v_j: at most 2 v_max + |v_i + v_j|.
    fastest = 2.0 * MAX_SPEED + math.hypot(*(ego.velocity + neighbour.velocity))
    gap = math.hypot(*(ego.position - neighbour.position)) - ego.radius - neighbour.radius
    return gap < fastest * PERIOD


@pytest.mark.parametrize('model', ['rvo', 'prvo'])
def test_fallback_never_closes_on_a_near_neighbour_when_it_need_not(model):
    rng = np.random.default_rng(1401)
    config = PlannerConfig(model=model, max_speed=MAX_SPEED, num_directions=64, inertia=0.5,
                           passing_bias=0.1)
    headings = np.linspace(0.0, 2.0 * math.pi, 721)
    grid = (np.linspace(0.0, MAX_SPEED, 101)[:, None, None]
            * np.stack([np.cos(headings), np.sin(headings)], axis=1)).reshape(-1, 2)
    checked = 0
    for _ in range(40):
        ego, neighbours, v_pref = trapped_near_encounter(rng)
        result = plan_velocity(ego, neighbours, v_pref, config, previous=v_pref)
        if result.candidates_feasible:
            continue
        near = [neighbour for neighbour in neighbours if within_one_period(ego, neighbour)]
        assert near
        # Whenever some command on a fine grid recedes from every near neighbour, so does the
        # chosen one.
        grid_closing = np.max([closing_speed(ego, neighbour, grid) for neighbour in near],
                              axis=0)
        if grid_closing.min() > 0.0:
            continue
        chosen = max(float(closing_speed(ego, neighbour, result.velocity)) for neighbour in near)
        assert chosen <= 1e-6, (chosen, result.velocity)
        checked += 1
    assert checked >= 10


def deepest_contact(ego, neighbours, velocity):
    """How far COMMAND moves into contact with any neighbour within one period, metres (>= 0).

    Sampled: the relative position ``r + t u`` (reciprocal ``u``) at 1001 times of the period;
    for a neighbour already touching, how much closer it comes than it is now.
    """
    times = np.linspace(0.0, PERIOD, 1001)[:, None]
    deepest = 0.0
    for neighbour in neighbours:
        offset = ego.position - neighbour.position
        relative = 2.0 * np.asarray(velocity) - ego.velocity - neighbour.velocity
        radius = ego.radius + neighbour.radius
        closest = np.linalg.norm(offset + times * relative, axis=1).min()
        deepest = max(deepest, min(math.hypot(*offset), radius) - closest)
    return deepest


@pytest.mark.parametrize('model', ['rvo', 'prvo'])
def test_fallback_does_not_move_into_contact_when_it_need_not(model):
    rng = np.random.default_rng(1402)
    config = PlannerConfig(model=model, max_speed=MAX_SPEED, num_directions=64, inertia=0.5,
                           passing_bias=0.1)
    checked = 0
    for _ in range(40):
        ego, neighbours, v_pref = trapped_near_encounter(rng)
        result = plan_velocity(ego, neighbours, v_pref, config, previous=v_pref)
        if result.candidates_feasible:
            continue
        # Standing still moves into contact with nobody here (the sampled geometry says so):
        # the chosen command must not either.
        if deepest_contact(ego, neighbours, np.zeros(2)) > 0.0:
            continue
        assert deepest_contact(ego, neighbours, result.velocity) <= 1e-6, result.velocity
        checked += 1
    assert checked >= 10


def test_control_period_is_checked_and_the_agent_plans_with_the_period_it_measures():
    with pytest.raises(ValueError, match='PlannerConfig.control_period must be > 0, got 0.0'):
        PlannerConfig(control_period=0.0)
    settings = AgentSettings(radius=RADIUS, unknown_neighbor_radius=RADIUS, approach_time=0.5,
                             goal_tolerance=0.2, acceleration_std=1.0, neighbor_timeout=2.0)
    agent = PlannerAgent('self', PlannerConfig(model='rvo'), settings, goal=[4.0, 0.0])
    periods = []
    for step in range(3):
        stamp = 0.25 * step
        agent.receive_own(OwnMeasurement(stamp, np.array([0.0, 0.0]), np.zeros(2),
                                         1e-4 * np.eye(4)), stamp)
        request = agent.plan_request()
        periods.append(request.problem[3].control_period)
        agent.complete(request, plan_velocity(*request.problem))
    # Before a period is known the configured one stands in; then the stamps' spacing.
    assert periods == [0.1, 0.25, 0.25]
