"""Standing still on the means: the RVO conditions at zero against geometry and the plan."""

import dataclasses
import math

import numpy as np
import pytest

from prvo_planner import agent as agent_module
from prvo_planner.agent import nobody_comes
from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.core.moments import condition_moments
from prvo_planner.core.standing import condition_change, standing_decided

CONFIG = PlannerConfig(eta=0.8, max_speed=1.0, time_horizon=5.0)
STANDING_SPEED = 1e-6
RADIUS = 0.3


def ego(velocity=(0.0, 0.0)):
    return AgentBelief([0.0, 0.0], velocity, 0.01 * np.eye(4), RADIUS)


def neighbour(position, velocity, share=0.0, radius=RADIUS):
    return AgentBelief(position, velocity, 0.01 * np.eye(4), radius, share)


def problem(neighbours, config=CONFIG, v_pref=(0.0, 0.0), own=None):
    return (ego() if own is None else own, list(neighbours), np.asarray(v_pref, dtype=float),
            config, None, None)


def planned(problem):
    """Return whether the deterministic RVO plan stands (`nobody_comes` by a whole plan)."""
    ego, neighbours, v_pref, config = problem[:4]
    result = plan_velocity(ego, neighbours, v_pref,
                           dataclasses.replace(config, model='rvo', inertia=0.0))
    return result.feasible and float(np.hypot(*result.velocity)) <= STANDING_SPEED


@pytest.fixture
def no_plans(monkeypatch):
    """Fail any plan `nobody_comes` would make: the conditions at zero must decide."""
    def refuse(*args, **kwargs):
        raise AssertionError('nobody_comes planned')
    monkeypatch.setattr(agent_module, 'plan_velocity', refuse)


# Hand-computed cases: the ego stands at the origin (R = 0.6 with both radii), the neighbour
# announces no share, so w = -v_j and r = -p_j.

def test_a_standing_neighbour_does_not_come(no_plans):
    # w = 0: f = g = h1 = 0, but h3 = (1 - eps) d^2 - R^2 = R d - R^2 = 0.6 * 1.4 > 0.
    assert nobody_comes(problem([neighbour([2.0, 0.0], [0.0, 0.0])]))


def test_a_neighbour_heading_at_the_robot_within_the_horizon_comes(no_plans):
    # r = (-2, 0), w = (1, 0): f = -R^2 < 0, g = -2, h1 = 2 - 5 < 0, and
    # h3 = (1 - eps) (4 - 25 / eps) - R^2 < 0 with eps = 1 - 0.6 / 2 = 0.7.
    assert not nobody_comes(problem([neighbour([2.0, 0.0], [-1.0, 0.0])]))


def test_a_neighbour_heading_at_the_robot_beyond_the_horizon_does_not_come(no_plans):
    # With tau = 1: h1 = 2 - 1 = 1 > 0 and h2 = |(-2, 0) + (1, 0)|^2 - R^2 = 0.64 > 0.
    short = dataclasses.replace(CONFIG, time_horizon=1.0)
    assert nobody_comes(problem([neighbour([2.0, 0.0], [-1.0, 0.0])], short))
    # Half a metre nearer, h2 = 0 - R^2 < 0, and h3 = 0.3 (2.25 - 1 / 0.6) - 0.36 < 0.
    assert not nobody_comes(problem([neighbour([1.5, 0.0], [-1.0, 0.0])], short))


def test_a_neighbour_passing_by_or_moving_away_does_not_come(no_plans):
    # Passing: r x w = (-2)(-1) = 2, f = 4 - R^2 > 0.
    assert nobody_comes(problem([neighbour([2.0, 0.0], [0.0, 1.0])]))
    # Moving away: g = r . w = 2 > 0 (the receding gate).
    assert nobody_comes(problem([neighbour([2.0, 0.0], [1.0, 0.0])]))


def test_without_the_receding_gate_a_neighbour_moving_away_counts_on_the_horizon(no_plans):
    # f = -R^2, h1 = -2 - tau < 0; h3 = 0.3 (4 - tau^2 / 0.7) - R^2: < 0 at tau = 5, > 0 at 1.
    gateless = dataclasses.replace(CONFIG, receding_gate=False)
    away = [neighbour([2.0, 0.0], [1.0, 0.0])]
    assert not nobody_comes(problem(away, gateless))
    assert nobody_comes(problem(away, dataclasses.replace(gateless, time_horizon=1.0)))


def test_a_reciprocal_neighbour_counts_the_robots_own_velocity(no_plans):
    # Share 1/2: w = -v_i - v_j. The ego drifting at (0.5, 0) toward a neighbour moving
    # (-0.5, 0) leaves w = 0 (the pair stands relative to each other): nobody comes.
    drifting = ego([0.5, 0.0])
    assert nobody_comes(problem([neighbour([2.0, 0.0], [-0.5, 0.0], share=0.5)], own=drifting))
    # Against a standing neighbour, w = -v_i: standing still against its own drift reads as
    # the opposite motion, as RVO's u = 2 v - v_i - v_j does at v = 0. Drifting toward the
    # neighbour, w = (-0.5, 0) recedes (g = r . w = 1 > 0); drifting away, w = (0.5, 0) closes
    # from 2 m at 0.5 m/s within tau = 5 (g = -1, h1 = 1 - 1.25, h3 = 0.3 (4 - 6.25 / 0.7) -
    # R^2, all < 0).
    standing = [neighbour([2.0, 0.0], [0.0, 0.0], share=0.5)]
    assert nobody_comes(problem(standing, own=drifting))
    assert not nobody_comes(problem(standing, own=ego([-0.5, 0.0])))


def test_overlapping_and_distant_neighbours(no_plans):
    # Mean disks overlapping: no velocity is feasible.
    assert not nobody_comes(problem([neighbour([0.5, 0.0], [0.0, 0.0])]))
    # Farther than neighbor_distance (surfaces 10 m apart): not considered, even coming.
    assert nobody_comes(problem([neighbour([10.7, 0.0], [-1.0, 0.0])]))
    assert nobody_comes(problem([]))


def test_one_neighbour_coming_among_standing_ones_is_enough(no_plans):
    standing = [neighbour([0.0, 2.0], [0.0, 0.0]), neighbour([-2.0, 0.0], [0.0, 0.0])]
    assert nobody_comes(problem(standing))
    assert not nobody_comes(problem([*standing, neighbour([2.0, 0.0], [-1.0, 0.0])]))


def test_standing_on_an_edge_is_left_to_the_plan():
    # No horizon and w = 0: f = g = 0 exactly, the plan's choice of heading decides.
    endless = dataclasses.replace(CONFIG, time_horizon=math.inf)
    edge = problem([neighbour([2.0, 0.0], [0.0, 0.0])], endless)
    assert standing_decided(*edge[:2], endless, STANDING_SPEED) is None
    assert nobody_comes(edge) == planned(edge)
    # Closing at 1e-7 m/s, 5.5 m from a collision: the plan may stand (the neighbour rejects
    # zero, but not a velocity 1e-7 m/s away from it).
    creeping = problem([neighbour([2.0, 0.0], [-1e-7, 0.0])], endless)
    assert standing_decided(*creeping[:2], endless, STANDING_SPEED) is None
    assert nobody_comes(creeping) == planned(creeping)
    # So is a robot that prefers to move, or a speed whose interior choice exceeds the
    # standing speed.
    moving = problem([neighbour([2.0, 0.0], [0.0, 1.0])], v_pref=(0.5, 0.0))
    assert nobody_comes(moving) == planned(moving) is False
    fast = dataclasses.replace(CONFIG, max_speed=2000.0)
    assert standing_decided(ego(), [], fast, STANDING_SPEED) is None


def test_the_change_bound_holds_over_commands_within_reach():
    # Sampled commands within the reach never move a condition further than the bound.
    rng = np.random.default_rng(3)
    count = 200
    origin = np.concatenate([rng.uniform(-3.0, 3.0, (count, 2)),
                             rng.uniform(-1.5, 1.5, (count, 2))], axis=1)
    radius = rng.uniform(0.4, 1.0, count)
    reach = rng.uniform(0.0, 0.5, count)
    for tau in (math.inf, 2.0):
        bound = condition_change(origin, radius, reach, tau)
        at_zero, _ = condition_moments(origin, np.zeros((count, 4, 4)), radius,
                                       np.zeros((1, 2)), tau, True, 1.0)
        angles = rng.uniform(0.0, 2.0 * np.pi, 64)
        scale = rng.uniform(0.0, 1.0, 64)
        commands = reach[:, None, None] * (scale[:, None] * np.stack(
            [np.cos(angles), np.sin(angles)], axis=1))[None]
        moved, _ = condition_moments(origin, np.zeros((count, 4, 4)), radius, commands, tau,
                                     True, 1.0)
        assert np.all(np.abs(moved - at_zero).max(axis=(1, 2)) <= bound * (1 + 1e-9) + 1e-12)


def random_problem(rng):
    """Return a robot at its goal among 1-6 neighbours: standing, creeping or coming."""
    config = dataclasses.replace(
        CONFIG, time_horizon=float(rng.choice([1.0, 3.0, 5.0, math.inf])),
        receding_gate=bool(rng.random() < 0.8), safety_margin=float(rng.choice([0.0, 0.05])),
        neighbor_distance=float(rng.choice([3.0, 10.0])))
    own_velocity = rng.choice([0.0, 1e-8, 0.05], size=2) * rng.choice([-1.0, 1.0], size=2)
    neighbours = []
    for _ in range(int(rng.integers(1, 7))):
        angle = rng.uniform(0.0, 2.0 * np.pi)
        distance = rng.uniform(0.5, 5.0)
        position = distance * np.array([math.cos(angle), math.sin(angle)])
        kind = rng.integers(4)
        if kind == 0:
            velocity = np.zeros(2)
        elif kind == 1:
            velocity = rng.normal(0.0, 1e-7, 2)
        elif kind == 2:
            # Toward the robot, off its centre by up to a metre.
            aim = rng.uniform(-1.0, 1.0) * np.array([-math.sin(angle), math.cos(angle)])
            velocity = (aim - position) / np.hypot(*(aim - position)) * rng.uniform(0.1, 1.0)
        else:
            velocity = rng.uniform(-1.0, 1.0, 2)
        neighbours.append(AgentBelief(position, velocity, 0.01 * np.eye(4),
                                      float(rng.uniform(0.2, 0.5)),
                                      float(rng.choice([0.0, 0.5]))))
    return problem(neighbours, config, own=AgentBelief([0.0, 0.0], own_velocity,
                                                       0.01 * np.eye(4), RADIUS))


def test_nobody_comes_answers_as_the_deterministic_plan_on_random_encounters():
    rng = np.random.default_rng(40)
    answers, decided = [], 0
    for _ in range(600):
        case = random_problem(rng)
        answer = nobody_comes(case)
        assert answer == planned(case), case
        answers.append(answer)
        decided += standing_decided(*case[:2], case[3], STANDING_SPEED) is not None
    # Both answers occur, and the conditions at zero decide almost every case.
    assert 0.2 < np.mean(answers) < 0.8
    assert decided >= 0.9 * len(answers)
