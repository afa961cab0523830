"""The ROS-free PlannerAgent: plans as the core does, refuses bad stamps, waits for neighbours."""

import dataclasses
import subprocess

import numpy as np
import pytest

from prvo_planner.agent import (
    MAX_STAMP_JUMP_SECONDS,
    AgentSettings,
    PlannerAgent,
)
from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.estimation import ConstantVelocityTracker

GOAL = np.array([4.0, 0.5])
SETTINGS = AgentSettings(radius=0.3, neighbor_radius=0.4, approach_time=0.5, goal_tolerance=0.2,
                         acceleration_std=1.0, neighbor_timeout=2.0)
CONFIG = PlannerConfig(eta=0.8, max_speed=1.0, actuation_cov=0.0025 * np.eye(2),
                       inertia=0.5, passing_bias=0.1)


@dataclasses.dataclass(frozen=True)
class Measurement:
    """The fields of prvo_msgs_util.OdometryMeasurement the agent reads."""

    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0


def measurements(seed, start, velocity, steps, dt=0.1, t0=0.0):
    """Return noisy measurements of a robot moving at constant VELOCITY from START."""
    rng = np.random.default_rng(seed)
    covariance = np.diag([0.0025, 0.0025, 0.0025, 0.0025])
    result = []
    for step in range(steps):
        stamp = t0 + step * dt
        truth = np.concatenate([np.asarray(start) + np.asarray(velocity) * step * dt, velocity])
        noisy = truth + rng.normal(0.0, 0.05, 4)
        result.append(Measurement(round(stamp, 9), noisy[:2], noisy[2:], covariance, 0.1))
    return result


def team(steps=12, t0=0.0):
    """Return the own robot's and two neighbours' measurements of a crossing encounter."""
    return {'self': measurements(1, [0.0, 0.0], [0.8, 0.0], steps, t0=t0),
            'a': measurements(2, [3.0, 0.2], [-0.8, 0.0], steps, t0=t0),
            'b': measurements(3, [1.5, -2.0], [0.0, 0.7], steps, t0=t0)}


def run(agent, data, steps, now=0.0):
    """Feed DATA step by step (neighbours first) and return every plan's Command."""
    commands = []
    for step in range(steps):
        for robot in ('a', 'b'):
            assert agent.receive_neighbour(robot, data[robot][step], now).accepted
        assert agent.receive_own(data['self'][step], now).accepted
        assert agent.ready(now)
        commands.append(agent.plan())
    return commands


def test_agent_plans_as_the_core_does_on_the_tracked_beliefs():
    data = team()
    commands = run(PlannerAgent('self', CONFIG, SETTINGS, GOAL), data, 12)
    trackers = {robot: ConstantVelocityTracker(1.0) for robot in data}
    previous = None
    for step, command in enumerate(commands):
        for robot, tracker in trackers.items():
            m = data[robot][step]
            tracker.update(m.stamp, m.position, m.velocity, m.covariance)
        own = trackers['self'].belief_at(command.stamp)
        offset = GOAL - own.mean[:2]
        distance = np.hypot(*offset)
        # Far from the goal: full speed straight at it; the horizon is capped by the way there.
        v_pref = offset / distance * min(1.0, distance / 0.5)
        horizon = min(CONFIG.time_horizon, distance / 1.0 + 0.5)
        neighbours = [AgentBelief(b.mean[:2], b.mean[2:], b.covariance, 0.4) for b in (
            trackers[robot].belief_at(command.stamp) for robot in ('a', 'b'))]
        expected = plan_velocity(
            AgentBelief(own.mean[:2], own.mean[2:], own.covariance, 0.3), neighbours, v_pref,
            dataclasses.replace(CONFIG, time_horizon=horizon), previous=previous)
        np.testing.assert_array_equal(command.velocity, expected.velocity)
        assert command.stamp == data['self'][step].stamp and command.yaw == 0.1
        previous = expected.velocity


@pytest.mark.parametrize('far_stamp', [2.0 ** 31 - 1.0, 1.7e9, 1.0 + MAX_STAMP_JUMP_SECONDS + 0.1])
@pytest.mark.parametrize('robot', ['self', 'a'])
def test_a_stamp_far_ahead_is_refused_and_changes_nothing(far_stamp, robot):
    data = team()
    reference, agent = (PlannerAgent('self', CONFIG, SETTINGS, GOAL) for _ in range(2))
    expected = run(reference, data, 12)
    actual = run(agent, data, 6, now=0.0)
    bad = dataclasses.replace(data[robot][5], stamp=far_stamp)
    fusion = (agent.receive_own(bad, 0.5) if robot == 'self'
              else agent.receive_neighbour(robot, bad, 0.5))
    assert fusion.status == 'refused' and f'{far_stamp:.3f} s' in fusion.detail
    assert agent.pending_stamp is None
    actual += run(agent, {name: series[6:] for name, series in data.items()}, 6, now=1.0)
    for mine, theirs in zip(actual, expected, strict=True):
        np.testing.assert_array_equal(mine.velocity, theirs.velocity)


@pytest.mark.parametrize('robot', ['self', 'a'])
def test_a_single_stamp_from_the_past_does_not_derail_the_track(robot):
    data = team(t0=50.0)
    reference, agent = (PlannerAgent('self', CONFIG, SETTINGS, GOAL) for _ in range(2))
    expected = run(reference, data, 12)
    actual = run(agent, data, 6)
    stray = dataclasses.replace(data[robot][5], stamp=0.0, position=np.array([9.0, 9.0]))
    fusion = (agent.receive_own(stray, 0.5) if robot == 'self'
              else agent.receive_neighbour(robot, stray, 0.5))
    assert fusion.status == 'restarted' and 'jumped back' in fusion.detail
    actual += run(agent, {name: series[6:] for name, series in data.items()}, 6)
    for mine, theirs in zip(actual, expected, strict=True):
        np.testing.assert_array_equal(mine.velocity, theirs.velocity)


def test_a_source_that_restarts_gets_a_new_track():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    run(agent, team(t0=30.0), 5)
    restarted = team(t0=0.0)
    assert agent.receive_neighbour('a', restarted['a'][0], 1.0).status == 'restarted'
    assert agent.receive_neighbour('a', restarted['a'][1], 1.0).status == 'fused'
    # The old track is gone for good: a stamp of the old time is now far ahead.
    assert agent.receive_neighbour('a', team(t0=30.0)['a'][5], 1.0).status == 'refused'


def test_time_far_ahead_is_accepted_after_a_neighbour_timeout_without_usable_stamps():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    run(agent, team(), 3)
    later = team(t0=100.0)
    assert agent.receive_own(later['self'][0], 1.0).status == 'refused'
    assert agent.receive_own(later['self'][1], 2.5).status == 'restarted'
    assert agent.pending_stamp == later['self'][1].stamp


def test_plans_wait_for_every_neighbour_and_listed_ones_at_start():
    data = team()
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL, listed_neighbours=['a', 'b', 'self'])
    agent.receive_neighbour('a', data['a'][0], 0.0)
    agent.receive_own(data['self'][0], 0.0)
    # b is listed and not heard yet: wait for it, up to neighbor_timeout after the first odometry.
    assert agent.awaiting_listed(1.0) and not agent.ready(1.0)
    assert not agent.awaiting_listed(2.5) and agent.ready(2.5)
    agent.receive_neighbour('b', data['b'][0], 1.0)
    assert agent.ready(1.0)
    agent.plan()
    assert agent.pending_stamp is None and not agent.ready(1.0)
    # A neighbour behind the own stamp holds the plan until it catches up (or the caller's
    # sync_timeout runs out and it plans anyway, b predicted to the stamp).
    agent.receive_neighbour('a', data['a'][1], 1.1)
    agent.receive_own(data['self'][1], 1.1)
    assert not agent.ready(1.1)
    command = agent.plan()
    assert len(command.neighbours) == 2 and command.neighbours[1].stamp == data['self'][1].stamp


def test_silent_and_unwanted_neighbours_are_forgotten():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    data = team()
    agent.receive_neighbour('a', data['a'][0], 0.0)
    agent.receive_neighbour('b', data['b'][0], 1.0)
    assert agent.forget_neighbours(2.5) == [('a', 2.5)]
    assert agent.forget_neighbours(2.5, wanted={'a'}) == [('b', 1.5)]
    assert agent.neighbours == set()


def test_no_goal_or_arrived_stands_still_without_a_plan():
    data = team()
    agent = PlannerAgent('self', CONFIG, SETTINGS)
    agent.receive_own(data['self'][0], 0.0)
    command = agent.plan()
    assert command.result is None and not command.velocity.any() and not command.arrived
    agent.set_goal(data['self'][0].position + [0.05, 0.0])
    agent.receive_own(data['self'][1], 0.0)
    command = agent.plan()
    assert command.arrived and command.result is None
    with pytest.raises(RuntimeError, match='pending'):
        agent.plan()


def test_the_agent_imports_no_ros(python_executable):
    probe = ('import sys, prvo_planner.agent; print(sorted(m for m in sys.modules '
             'if m.split(".")[0] in ("rclpy", "rcl_interfaces", "prvo_msgs_util")))')
    output = subprocess.run([python_executable, '-c', probe], capture_output=True, text=True,
                            check=True).stdout
    assert output.strip() == '[]', output


def test_a_neighbour_heard_again_after_it_was_dropped_is_resumed():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    data = team(t0=30.0)
    assert agent.receive_neighbour('a', data['a'][0], 0.0).status == 'fused'
    assert [robot for robot, _ in agent.forget_neighbours(10.0)] == ['a']
    fusion = agent.receive_neighbour('a', team(t0=0.0)['a'][0], 10.5)
    assert fusion.status == 'resumed' and fusion.accepted and 'again' in fusion.detail
    assert agent.receive_neighbour('a', team(t0=0.0)['a'][1], 10.6).status == 'fused'


def _plan_at(agent, stamp, position):
    agent.receive_own(Measurement(stamp, np.asarray(position), np.zeros(2), 1e-8 * np.eye(4)),
                      stamp)
    return agent.plan()


def test_an_arrival_counts_once_until_the_robot_left_the_goal_or_got_a_new_one():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    tolerance = SETTINGS.goal_tolerance
    # Measurements a second apart: the tracked position follows them closely.
    offsets = [0.25, 1.5, 0.25, 1.5, 0.25, 3.0, 3.0, 3.0, 0.25, 0.25, 0.25, 0.25]
    commands = [_plan_at(agent, float(step), GOAL - [offset * tolerance, 0.0])
                for step, offset in enumerate(offsets, start=1)]
    arrivals = [command.arrival for command in commands]
    # Noise in and out of the tolerance: the first arrival only.
    assert arrivals[:5] == [True, False, False, False, False]
    assert [command.arrived for command in commands[:5]] == [True, False, True, False, True]
    # Back from 0.6 m (three tolerances): one more arrival, once the robot is in again.
    assert not any(command.arrived for command in commands[5:8])
    assert sum(arrivals[8:]) == 1 and commands[-1].arrived
    agent.set_goal(GOAL + [0.1, 0.0])
    assert _plan_at(agent, 13.0, GOAL).arrival
