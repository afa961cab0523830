"""The stall rule of prvo_planner.stalls, on hand-built trajectories."""

import math

import numpy as np
import pytest

from prvo_planner import stalls
from prvo_planner.stalls import SPOT_RADIUS, STALL_WINDOW, StallMonitor

DT = 0.1  # s between updates
GOAL = np.array([10.0, 0.0])
TOLERANCE = 0.2  # m


def watch(positions, goal=GOAL, dt=DT, monitor=None, first=0):
    """Feed POSITIONS (T, 2) DT apart from step FIRST to MONITOR (a new one); return statuses."""
    monitor = StallMonitor() if monitor is None else monitor
    return [monitor.update(round((first + index) * dt, 9), position, goal, TOLERANCE)
            for index, position in enumerate(positions)]


def line(speed, duration, start=0.0, dt=DT):
    """Positions of a robot driving along y = 0 from x = START at SPEED [m/s] for DURATION."""
    times = np.arange(round(duration / dt) + 1) * dt
    return np.column_stack([start + speed * times, 0.0 * times])


def test_a_robot_that_gains_0_4_m_in_10_s_stalls_once_when_the_window_is_full():
    statuses = watch(line(0.04, 20.0))
    began = [status.time for status in statuses if status.began]
    assert began == [STALL_WINDOW]
    last = statuses[-1]
    assert last.stalled and last.since == STALL_WINDOW and last.stalls == 1
    assert last.duration == pytest.approx(10.0) and last.longest_stall == pytest.approx(10.0)
    assert last.gained == pytest.approx(0.4)
    first = statuses[round(STALL_WINDOW / DT)]
    np.testing.assert_allclose(first.position, [0.4, 0.0])
    assert first.distance_to_goal == pytest.approx(9.6)
    assert first.duration == 0.0


def test_a_stall_ends_when_the_robot_comes_0_5_m_closer_than_when_it_began():
    statuses = watch(line(0.04, 30.0))
    # Stalled at x = 0.4 m (t = 10 s); 0.5 m closer is x = 0.9 m, at t = 22.5 s.
    ends = [status.time for before, status in zip(statuses, statuses[1:], strict=False)
            if before.stalled and not status.stalled]
    assert ends == [pytest.approx(22.5)]
    # From x = 0.9 m the last 10 s gained 0.4 m again: a second stall at once.
    assert statuses[-1].stalls == 2
    assert statuses[-1].longest_stall == pytest.approx(12.5)


def test_a_robot_that_gains_0_6_m_in_10_s_does_not_stall():
    statuses = watch(line(0.06, 60.0))
    assert not any(status.stalled for status in statuses)
    assert statuses[-1].stalls == 0 and statuses[-1].longest_stall == 0.0
    assert statuses[-1].gained == pytest.approx(0.6)


def test_before_a_full_window_nobody_stalls_and_the_gain_is_unknown():
    statuses = watch(np.zeros((round(STALL_WINDOW / DT), 2)))
    assert not any(status.stalled for status in statuses)
    assert all(math.isnan(status.gained) for status in statuses)


def test_a_robot_that_arrives_slowly_from_close_by_does_not_stall():
    # 0.45 m from its goal at 0.03 m/s: 0.3 m in 10 s, but it reaches the tolerance (0.2 m).
    arriving = line(0.03, 40.0, start=GOAL[0] - 0.45)
    arriving[:, 0] = np.minimum(arriving[:, 0], GOAL[0] - 0.1)
    statuses = watch(arriving)
    assert not any(status.stalled for status in statuses)
    # Short of that, it would have had to reach the tolerance: from 0.4 m creeping 0.01 m/s it
    # does not, and stalls.
    creeping = watch(line(0.01, 15.0, start=GOAL[0] - 0.4))
    assert [status.time for status in creeping if status.began] == [STALL_WINDOW]


def test_a_robot_at_its_goal_that_steps_aside_for_less_than_the_window_does_not_stall():
    positions = np.tile(GOAL + [0.1, 0.0], (301, 1))
    aside = (np.arange(301) >= 50) & (np.arange(301) < 140)  # 9 s, 0.5 m off its goal
    positions[aside, 1] += 0.5
    statuses = watch(positions)
    assert not any(status.stalled for status in statuses)
    # Aside for 15 s, it stalls once the window holds no time at its goal, until it is back.
    positions[np.arange(301) < 200, 1] = 0.0
    positions[(np.arange(301) >= 50) & (np.arange(301) < 200), 1] += 0.5
    statuses = watch(positions)
    stalled = [status.time for status in statuses if status.stalled]
    assert stalled[0] == pytest.approx(15.0) and stalled[-1] == pytest.approx(19.9)
    assert statuses[-1].stalls == 1 and statuses[-1].longest_stall == pytest.approx(5.0)


def test_another_goal_ends_the_stall_and_restarts_the_window_but_keeps_the_counts():
    monitor = StallMonitor()
    standing = np.zeros((151, 2))
    assert watch(standing, monitor=monitor)[-1].stalled
    statuses = watch(standing, goal=np.array([0.0, 10.0]), monitor=monitor, first=151)
    assert not statuses[0].stalled and statuses[0].stalls == 1
    assert statuses[0].longest_stall == pytest.approx(5.0)
    assert [status.time for status in statuses if status.began] == [pytest.approx(25.1)]
    # No goal: nothing to stall from.
    idle = monitor.update(40.0, np.zeros(2), None, TOLERANCE)
    assert not idle.stalled and idle.distance_to_goal == math.inf and idle.stalls == 2


def test_the_way_left_along_a_route_is_the_distance_when_given():
    # Around a wall the straight line to the goal grows while the way left shrinks: no stall.
    monitor = StallMonitor()
    for index in range(301):
        time = index * DT
        status = monitor.update(time, [0.0, -0.1 * time], GOAL, TOLERANCE,
                                distance=40.0 - 0.1 * time)
        assert not status.stalled
    assert status.distance_to_goal == pytest.approx(37.0)
    # An infinite way left (no route) falls back to the straight line.
    assert monitor.update(30.1, [0.0, 0.0], GOAL, TOLERANCE,
                          distance=math.inf).distance_to_goal == 10.0


def test_the_memory_is_one_window_of_updates():
    monitor = StallMonitor()
    watch(line(0.01, 1000.0), monitor=monitor)
    assert len(monitor._history) <= round(STALL_WINDOW / DT) + 1


def longest_dwell_by_definition(times, positions, distances):
    """Return the longest dwell of the module's definition, computed spot after spot."""
    longest, start, count = 0.0, 0, len(times)
    while start < count:
        if distances[start] <= TOLERANCE:
            start += 1
            continue
        away = np.linalg.norm(positions[start:] - positions[start], axis=1) > SPOT_RADIUS
        at_goal = distances[start:] <= TOLERANCE
        ends = np.flatnonzero(away | at_goal)
        end = start + (ends[0] if ends.size else count - start)
        longest = max(longest, times[end - 1] - times[start])
        start = end
    return longest


def test_the_longest_dwell_is_the_longest_stay_near_one_spot_away_from_the_goal():
    # Drive 3 s at 1 m/s, stand 7 s, drive on to the goal and wait there 20 s.
    positions = np.concatenate([line(1.0, 3.0)[:-1], np.tile([3.0, 0.0], (70, 1)),
                                line(1.0, 7.0, start=3.0), np.tile(GOAL, (200, 1))])
    statuses = watch(positions)
    # The stand, and at most the last 0.5 m driven before it; the wait at the goal is no dwell.
    assert 7.0 - 1e-9 <= statuses[-1].longest_dwell <= 7.5
    times = np.arange(len(positions)) * DT
    distances = np.linalg.norm(GOAL - positions, axis=1)
    assert statuses[-1].longest_dwell == pytest.approx(
        longest_dwell_by_definition(times, positions, distances))


@pytest.mark.parametrize('seed', range(5))
def test_the_longest_dwell_of_a_random_walk_matches_the_definition(seed):
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, 0.08, (600, 2)) * rng.choice([0.2, 1.0, 3.0], (600, 1))
    positions = GOAL + [-3.0, 0.0] + np.cumsum(steps, axis=0)
    statuses = watch(positions)
    times = np.arange(len(positions)) * DT
    distances = np.linalg.norm(GOAL - positions, axis=1)
    assert statuses[-1].longest_dwell == pytest.approx(
        longest_dwell_by_definition(times, positions, distances))


def test_a_trajectory_summary_counts_every_robot():
    times = np.arange(301) * DT
    stuck = np.zeros((301, 2))
    moving = line(0.1, 30.0)
    summary = stalls.trajectory_stalls(times, np.stack([stuck, moving], axis=1),
                                       np.array([GOAL, GOAL]), TOLERANCE)
    # The stuck robot stalls at 10 s, for 20 s, near its spot for 30 s; the mover never.
    assert summary == {'stalls': 1, 'longest_stall_s': 20.0, 'longest_dwell_s': 30.0}
