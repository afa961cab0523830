"""Stall detection over a window of distances to the goal, and the detour to the right."""

import math

import numpy as np
import pytest

from prvo_planner.core.progress import ProgressWindow, detour, stalled

DT = 0.1


def window_of(distances, window=2.0, dt=DT):
    """Return a ProgressWindow fed DISTANCES at stamps 0, dt, 2 dt, ..."""
    progress = ProgressWindow(window)
    for step, distance in enumerate(distances):
        progress.add(round(step * dt, 9), distance)
    return progress


def test_progress_is_the_distance_gained_since_the_window_start():
    # 4 s of a robot closing in at 0.3 m/s: over the last 2 s it gained 0.6 m.
    distances = [10.0 - 0.3 * DT * step for step in range(41)]
    progress, elapsed, start = window_of(distances).progress()
    assert elapsed == pytest.approx(2.0)
    assert progress == pytest.approx(0.6)
    assert start == pytest.approx(distances[20])


def test_no_verdict_before_the_window_is_full():
    distances = [10.0] * 20  # 1.9 s of standing still
    progress = window_of(distances)
    assert progress.progress() is None
    assert not stalled(progress, 1.0, 0.25, 0.2)


@pytest.mark.parametrize('speed, expected', [(0.0, True), (0.2, True), (0.3, False),
                                             (1.0, False), (-0.5, True)])
def test_stalled_below_the_fraction_of_full_speed(speed, expected):
    # Threshold: 0.25 of 1 m/s over 2 s = 0.5 m, i.e. 0.25 m/s on average.
    distances = [10.0 - speed * DT * step for step in range(31)]
    assert stalled(window_of(distances), 1.0, 0.25, 0.2) is expected


def test_circling_at_full_speed_is_a_stall():
    # Full speed on a circle round the goal: the distance does not shrink.
    assert stalled(window_of([3.0 + 0.01 * math.sin(step) for step in range(40)]), 1.0, 0.25,
                   0.2)


def test_slowing_down_at_the_goal_is_no_stall():
    # Near the goal the robot slows by design: what it could gain is only what is left.
    distances = [0.3 + 0.1 * 0.5 ** (DT * step) for step in range(30)]
    assert not stalled(window_of(distances), 1.0, 0.25, 0.2)
    assert not stalled(window_of([0.2] * 30), 1.0, 0.25, 0.2)


def test_stamps_must_not_go_back_and_the_window_must_be_positive():
    progress = window_of([1.0, 1.0])
    with pytest.raises(ValueError, match='stamp'):
        progress.add(0.0, 1.0)
    with pytest.raises(ValueError, match='window'):
        ProgressWindow(0.0)


def test_detour_turns_right_by_the_angle():
    v_pref = np.array([0.6, 0.8])
    turned = detour(v_pref, 0.5)
    assert np.hypot(*turned) == pytest.approx(1.0)
    # Clockwise: the turned vector is to the right of v_pref (negative cross product) and
    # makes the angle with it.
    assert v_pref[0] * turned[1] - v_pref[1] * turned[0] == pytest.approx(-math.sin(0.5))
    assert float(np.dot(v_pref, turned)) == pytest.approx(math.cos(0.5))
