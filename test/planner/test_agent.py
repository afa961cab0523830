"""The ROS-free PlannerAgent: plans as the core does, refuses bad stamps, waits for neighbours."""

import dataclasses
import subprocess

import numpy as np
from planner_testing import Odometry
import pytest

from prvo_planner import tracking
from prvo_planner.agent import (
    AgentSettings,
    NeighbourAnnouncement,
    PlannerAgent,
)
from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.estimation import ConstantVelocityTracker
from prvo_planner.preferred import PATH
from prvo_planner.tracks import MAX_STAMP_JUMP_SECONDS, TrackTable

GOAL = np.array([4.0, 0.5])
# Keep right off (test_lanes, test_lane_runs): the preference is the goal's, as the core has it.
SETTINGS = AgentSettings(radius=0.3, unknown_neighbor_radius=0.4, approach_time=0.5,
                         goal_tolerance=0.2, acceleration_std=1.0, neighbor_timeout=2.0,
                         keep_right=0.0)
CONFIG = PlannerConfig(eta=0.8, max_speed=1.0, actuation_cov=0.0025 * np.eye(2),
                       inertia=0.5, passing_bias=0.1)


def measurements(seed, start, velocity, steps, dt=0.1, t0=0.0):
    """Return noisy measurements of a robot moving at constant VELOCITY from START."""
    rng = np.random.default_rng(seed)
    covariance = np.diag([0.0025, 0.0025, 0.0025, 0.0025])
    result = []
    for step in range(steps):
        stamp = t0 + step * dt
        truth = np.concatenate([np.asarray(start) + np.asarray(velocity) * step * dt, velocity])
        noisy = truth + rng.normal(0.0, 0.05, 4)
        result.append(Odometry(round(stamp, 9), noisy[:2], noisy[2:], covariance, 0.1))
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


# Per neighbour: what it announced (radius, share; None: nothing) and what is planned with.
ANNOUNCED = {'a': ((0.7, 0.5), (0.7, 0.5)), 'b': ((None, None), (0.4, 0.0))}


@pytest.mark.parametrize('announce', [False, True])
def test_agent_plans_as_the_core_does_on_the_tracked_beliefs(announce):
    data = team()
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    planned_with = {robot: (0.4, 0.0) for robot in ANNOUNCED}
    if announce:
        for robot, ((radius, share), expected) in ANNOUNCED.items():
            if radius is not None:
                agent.receive_footprint(robot, radius, 0.0)
                agent.receive_share(robot, share, 0.0)
            planned_with[robot] = expected
    commands = run(agent, data, 12)
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
        neighbours = [AgentBelief(b.mean[:2], b.mean[2:], b.covariance, *planned_with[robot])
                      for robot, b in ((robot, trackers[robot].belief_at(command.stamp))
                                       for robot in ('a', 'b'))]
        expected = plan_velocity(
            AgentBelief(own.mean[:2], own.mean[2:], own.covariance, 0.3), neighbours, v_pref,
            dataclasses.replace(CONFIG, time_horizon=horizon), previous=previous)
        np.testing.assert_array_equal(command.velocity, expected.velocity)
        assert command.stamp == data['self'][step].stamp and command.yaw == 0.1
        assert command.announcement_values() == {
            f'neighbour.{robot}.{key}': value for robot in ('a', 'b')
            for key, value in zip(('radius', 'avoidance_share'), planned_with[robot],
                                  strict=True)}
        previous = expected.velocity


@pytest.mark.parametrize('receive, value, stamp, fault', [
    (PlannerAgent.receive_footprint, 0.0, 0.0, 'radius must be finite and > 0, got 0.0'),
    (PlannerAgent.receive_footprint, float('nan'), 0.0, 'radius must be finite and > 0, got nan'),
    (PlannerAgent.receive_share, 1.0, 0.0, r'avoidance_share must be in \[0, 1\), got 1.0'),
    (PlannerAgent.receive_share, -0.1, 0.0, r'avoidance_share must be in \[0, 1\), got -0.1'),
    (PlannerAgent.receive_footprint, 0.6, -0.1, 'announcement stamp must be finite and >= 0, '
     'got -0.1'),
    (PlannerAgent.receive_share, 0.25, float('inf'), 'announcement stamp must be finite and '
     '>= 0, got inf')])
def test_a_bad_announcement_is_refused_and_the_neighbour_keeps_what_it_had(receive, value, stamp,
                                                                           fault):
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    with pytest.raises(ValueError, match=f'^{fault}$'):
        receive(agent, 'a', value, stamp)
    assert agent.announcement_of('a', 0.0) == NeighbourAnnouncement(0.4, 0.0)
    agent.receive_footprint('a', 0.8, 0.0)
    agent.receive_share('a', 0.5, 0.0)
    with pytest.raises(ValueError, match=f'^{fault}$'):
        receive(agent, 'a', value, stamp)
    assert agent.announcement_of('a', 0.1) == NeighbourAnnouncement(0.8, 0.5)
    agent.forget_announcements('a')
    assert agent.announcement_of('a', 0.1) == NeighbourAnnouncement(0.4, 0.0)


def test_the_robot_announces_its_radius_and_a_share_only_on_its_way():
    agent = PlannerAgent('self', CONFIG, SETTINGS)
    assert agent.own_announcement == NeighbourAnnouncement(0.3, 0.0)
    agent.set_goal(GOAL)
    assert agent.own_announcement == NeighbourAnnouncement(0.3, 0.5)
    agent.receive_own(standing(0.0, GOAL + [0.1, 0.0]), 0.0)
    agent.plan()
    assert agent.arrived and agent.own_announcement == NeighbourAnnouncement(0.3, 0.0)


def test_a_robot_waiting_for_its_path_announces_from_the_start_the_share_it_takes():
    # Its first plan is made on its path: a neighbour's first plan counts on its share whether
    # the announcement it heard was sent before or after the path came (a ROS run's first
    # commands otherwise depended on the order, issue 35).
    settings = dataclasses.replace(SETTINGS, preferred_source=PATH, wait_for_path=True)
    agent = PlannerAgent('self', CONFIG, settings)
    before = agent.own_announcement
    agent.set_path(np.array([[0.0, 0.0], GOAL]))
    assert before == agent.own_announcement == NeighbourAnnouncement(0.3, 0.5)
    assert agent.own_announcement_stamp == 0.0
    # Its wait ran out without a path: it planned standing, and says so from the next plan on.
    waited = PlannerAgent('self', CONFIG, settings)
    waited.receive_own(standing(0.0, [0.0, 0.0]), 0.0)
    assert waited.awaiting_listed(1.0) and waited.ready(2.5)
    waited.plan()
    assert waited.own_announcement == NeighbourAnnouncement(0.3, 0.0)
    assert waited.own_announcement_stamp > 0.0
    # Without the wait it plans at once, path or none: no share until it has a path.
    at_once = PlannerAgent('self', CONFIG, dataclasses.replace(SETTINGS, preferred_source=PATH))
    assert at_once.own_announcement == NeighbourAnnouncement(0.3, 0.0)


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
    for robot in ('a', 'b'):
        agent.receive_footprint(robot, 0.3, 0.0)
    agent.receive_share('a', 0.5, 0.0)
    agent.receive_neighbour('a', data['a'][0], 0.0)
    agent.receive_own(data['self'][0], 0.0)
    # b is listed and not heard yet: wait for it, up to neighbor_timeout after the first odometry.
    assert agent.awaiting_listed(1.0) and not agent.ready(1.0)
    assert not agent.awaiting_listed(2.5) and agent.ready(2.5)
    assert agent.unheard_listed() == ['b']  # a plan now would be made without b
    agent.receive_neighbour('b', data['b'][0], 1.0)
    # Heard in full only with its announcements: its share is still missing.
    assert agent.awaiting_listed(1.0) and not agent.ready(1.0)
    assert agent.unheard_listed() == ['b']
    agent.receive_share('b', 0.5, 0.0)
    assert agent.ready(1.0) and agent.unheard_listed() == []
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


def test_a_neighbour_repeating_its_state_is_not_silent():
    # A lockstep simulator re-sends t_0 until every node is up; under load that takes longer
    # than neighbor_timeout, and dropping the neighbours then would restart their tracks.
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    first = team()['a'][0]
    for now in (0.0, 1.5, 3.0, 4.5):
        agent.receive_neighbour('a', first, now)
    assert agent.forget_neighbours(5.0) == []
    ((robot, silent),) = agent.forget_neighbours(6.6)
    assert robot == 'a' and silent == pytest.approx(2.1)


def test_no_goal_stands_still_without_a_plan():
    data = team()
    agent = PlannerAgent('self', CONFIG, SETTINGS)
    agent.receive_own(data['self'][0], 0.0)
    command = agent.plan()
    assert command.result is None and not command.velocity.any() and not command.arrived
    with pytest.raises(RuntimeError, match='pending'):
        agent.plan()


def standing(stamp, position):
    return Odometry(stamp, np.asarray(position, dtype=float), np.zeros(2),
                       0.0001 * np.eye(4))


def test_a_robot_at_its_goal_stands_while_nobody_comes_and_steps_aside_when_someone_does():
    agent = PlannerAgent('self', CONFIG, SETTINGS, [0.0, 0.0])
    agent.receive_footprint('a', 0.3, 0.0)
    agent.receive_share('a', 0.5, 0.0)
    # A neighbour standing 8 m away: nobody comes, it stands without a plan, announcing that
    # it does not mirror anyone's moves.
    agent.receive_neighbour('a', standing(0.0, [8.0, 0.0]), 0.0)
    agent.receive_own(standing(0.0, [0.05, 0.0]), 0.0)
    command = agent.plan()
    assert command.arrived and command.result is None and not command.velocity.any()
    assert agent.own_announcement == NeighbourAnnouncement(0.3, 0.0)
    # A neighbour heading straight at it, 3 s away: standing still would be a collision within
    # the horizon, so it moves (its share of the avoidance).
    coming = Odometry(0.1, np.array([3.0, 0.0]), np.array([-1.0, 0.0]), 0.0001 * np.eye(4))
    agent.receive_neighbour('a', coming, 0.1)
    agent.receive_own(standing(0.1, [0.05, 0.0]), 0.1)
    command = agent.plan()
    assert command.arrived and command.result is not None
    assert np.hypot(*command.velocity) > 0.1
    # Sideways, not along the neighbour's line.
    assert abs(command.velocity[1]) > abs(command.velocity[0])


def test_the_agent_imports_no_ros(python_executable):
    probe = ('import sys, prvo_planner.agent; print(sorted(m for m in sys.modules '
             'if m.split(".")[0] in ("rclpy", "rcl_interfaces", "prvo_msgs_util")))')
    output = subprocess.run([python_executable, '-c', probe], capture_output=True, text=True,
                            check=True).stdout
    assert output.strip() == '[]', output


def test_the_nodes_import_scipy_special_and_sparse_only_when_they_need_them(python_executable):
    # Importing either costs every process 0.2-0.5 s of CPU; most nodes never call them.
    probe = ('import sys, prvo_planner.planner_node, prvo_sim.run_scenario, prvo_sim.sim_node, '
             'prvo_sim.upstream_node; print(sorted(m for m in sys.modules '
             'if m in ("scipy.special", "scipy.sparse")))')
    output = subprocess.run([python_executable, '-c', probe], capture_output=True, text=True,
                            check=True).stdout
    assert output.strip() == '[]', output


def test_agents_sharing_one_track_table_plan_as_agents_with_their_own():
    # Two robots heading at each other, planned once with a table each (as two nodes do) and
    # once sharing one table fed once per measurement (as the in-process engine does): the
    # same measurements at the same `now` must give the same commands, bit for bit.
    data = {'p': measurements(4, [0.0, 0.0], [0.8, 0.0], 12),
            'q': measurements(5, [3.0, 0.1], [-0.8, 0.0], 12)}
    goals = {'p': np.array([4.0, 0.0]), 'q': np.array([-1.0, 0.1])}
    own = {name: PlannerAgent(name, CONFIG, SETTINGS, goals[name]) for name in data}
    table = TrackTable(SETTINGS.acceleration_std, SETTINGS.neighbor_timeout)
    shared = {name: PlannerAgent(name, CONFIG, SETTINGS, goals[name], neighbour_tracks=table)
              for name in data}
    for step in range(12):
        now = 0.1 * step
        for name, agent in own.items():
            agent.receive_own(data[name][step], now)
            other = 'q' if name == 'p' else 'p'
            agent.receive_neighbour(other, data[other][step], now)
        for name, agent in shared.items():
            agent.receive_own(data[name][step], now)
            table.receive(name, data[name][step], now)
        for name in data:
            assert own[name].ready(now) and shared[name].ready(now)
            assert shared[name].neighbours == own[name].neighbours == {
                'q' if name == 'p' else 'p'}
            expected, got = own[name].plan(), shared[name].plan()
            assert np.array_equal(expected.velocity, got.velocity)
            assert len(got.neighbours) == 1


def test_a_tables_beliefs_at_a_stamp_are_its_tracks_until_one_changes():
    # Made once per stamp for every agent sharing the table, each leaving out itself; a
    # measurement or a dropped robot makes them anew.
    data = {name: measurements(seed, [float(seed), 0.0], [0.5, 0.0], 4)
            for seed, name in enumerate('abc')}
    table = TrackTable(SETTINGS.acceleration_std, SETTINGS.neighbor_timeout)

    def expected(stamp, excluded):
        names = tuple(name for name in table.names() if name != excluded)
        tracks = tuple(table.track(name) for name in names)
        return names, tracks, tuple(track.belief_at(stamp) for track in tracks)

    for step in range(3):
        for name in data:
            table.receive(name, data[name][step], 0.1 * step)
            for excluded in (None, 'a', 'b', 'c', 'd'):
                assert table.beliefs_at(0.1 * step + 0.05, excluded) == expected(
                    0.1 * step + 0.05, excluded)
    before = table.beliefs_at(0.3, 'a')[2]
    table.receive('b', data['b'][3], 0.3)
    after = table.beliefs_at(0.3, 'a')[2]
    assert after[0] is not before[0] and after[1] is before[1]
    assert after == expected(0.3, 'a')[2]
    table.forget(0.3, wanted={'a', 'c'})
    assert table.beliefs_at(0.3, 'a')[0] == ('c',)
    assert table.beliefs_at(0.3)[0] == ('a', 'c')


def unicycle_settings(**limits):
    return dataclasses.replace(SETTINGS, kinematics='unicycle', tracking_error=0.1,
                               tracking_horizon=0.5, **limits)


def test_a_unicycle_agent_plans_with_its_grown_radius_and_drives_forward_and_turns():
    agent = PlannerAgent('self', CONFIG, unicycle_settings(max_acceleration=1.0), goal=GOAL)
    drives = []
    for step, measurement in enumerate(team()['self']):
        agent.receive_own(measurement, step * 0.1)
        request = agent.plan_request()
        ego, _, _, _, _, limits = request.problem
        assert ego.radius == pytest.approx(0.4)
        assert limits.heading == 0.1 and limits.trackable_speed is not None
        result = plan_velocity(*request.problem)
        command = agent.complete(request, result)
        # The diagnostics' bound is the plan's, made with the grown radius.
        assert command.result is result
        drives.append(command.drive)
    forward = np.array([drive[0] for drive in drives])
    turn = np.array([drive[1] for drive in drives])
    # From rest: the forward speed rises by at most 1 m/s^2 x 0.1 s per plan; the first plan,
    # before any period is known, stays put.
    assert forward[0] == 0.0
    assert np.all(np.abs(np.diff(forward)) <= 0.1 + 1e-12) and forward[-1] > 0.3
    # The goal is a little to the left of the heading (yaw 0.1 rad): it turns toward it.
    assert np.all(np.abs(turn) <= 2.0)


@pytest.mark.parametrize('limits', [{'max_angular_speed': 1e-9},
                                    {'max_angular_acceleration': 1e-6}])
def test_a_unicycle_too_slow_to_turn_plans_after_bounded_work(monkeypatch, limits):
    """Limits the parameters refuse still plan: the tracking table's work is bounded.

    It used to simulate about pi / omega seconds of turning, some 1e10 control periods.
    """
    steps = []
    control_law = tracking._control_law

    def counted(*arguments):
        steps.append(1)
        if len(steps) > 10 * tracking.MAX_TABLE_PERIODS:
            raise AssertionError(f'more than {len(steps) - 1} control periods simulated')
        return control_law(*arguments)

    monkeypatch.setattr(tracking, '_control_law', counted)
    agent = PlannerAgent('self', CONFIG, unicycle_settings(**limits), goal=GOAL)
    data = team()['self']
    commands = []
    for step in range(2):
        agent.receive_own(data[step], step * 0.1)
        commands.append(agent.plan())
    # Two tables (the first plan's period is the tracking horizon, then 0.1 s) and one command
    # per plan.
    assert len(steps) <= 2 * tracking.MAX_TABLE_PERIODS + 2
    # Its goal lies 0.02 rad off its heading: it can track nothing but standing still.
    for command in commands:
        assert np.linalg.norm(command.velocity) < 1e-6 and command.drive == (0.0, 0.0)


def test_an_accelerating_agent_changes_its_command_by_at_most_the_limit_and_brakes():
    settings = dataclasses.replace(SETTINGS, max_acceleration=0.8)
    agent = PlannerAgent('self', CONFIG, settings, goal=[0.6, 0.0])
    previous = np.zeros(2)
    rng = np.random.default_rng(4)
    position = np.zeros(2)
    arrived_at = None
    for step in range(80):
        measured = Odometry(round(step * 0.1, 9), position + rng.normal(0.0, 0.01, 2),
                               previous + rng.normal(0.0, 0.01, 2), 1e-4 * np.eye(4))
        agent.receive_own(measured, step * 0.1)
        command = agent.plan()
        assert np.linalg.norm(command.velocity - previous) <= 0.08 + 1e-9, step
        previous = command.velocity
        position = position + previous * 0.1
        if command.arrived and arrived_at is None:
            arrived_at = step
    # It arrived and came to rest at the limit, near the goal: no overshoot beyond braking.
    assert arrived_at is not None and np.all(previous == 0.0)
    assert abs(position[0] - 0.6) < 0.15


def test_a_neighbour_heard_again_after_it_was_dropped_is_resumed():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    data = team(t0=30.0)
    assert agent.receive_neighbour('a', data['a'][0], 0.0).status == 'fused'
    assert [robot for robot, _ in agent.forget_neighbours(10.0)] == ['a']
    fusion = agent.receive_neighbour('a', team(t0=0.0)['a'][0], 10.5)
    assert fusion.status == 'resumed' and fusion.accepted and 'again' in fusion.detail
    assert agent.receive_neighbour('a', team(t0=0.0)['a'][1], 10.6).status == 'fused'


def _plan_at(agent, stamp, position):
    agent.receive_own(Odometry(stamp, np.asarray(position), np.zeros(2), 1e-8 * np.eye(4)),
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
