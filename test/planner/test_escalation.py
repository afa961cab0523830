"""Escalation (prvo_planner.escalation) alone: the turn to the right of a stalled robot."""

import math

import numpy as np
import pytest

from prvo_planner.escalation import (
    Escalation,
    EscalationSettings,
    turn_angle,
    turned_right,
)
from prvo_planner.stalls import StallStatus

SETTINGS = EscalationSettings(enabled=True, rate=0.2, cap=math.pi / 3.0)
EAST = np.array([1.0, 0.0])


def status(time, since):
    """Return a StallStatus at TIME [s], stalled since SINCE [s] (None: not stalled)."""
    return StallStatus(time=time, stalled=since is not None, began=since == time, since=since,
                       position=np.zeros(2), distance_to_goal=5.0, gained=0.0, stalls=1,
                       longest_stall=0.0, longest_dwell=0.0)


def test_the_angle_rises_at_the_rate_to_the_cap_falls_back_and_again():
    cap = math.pi / 3.0
    rise = cap / 0.2
    assert turn_angle(0.0, SETTINGS) == 0.0
    assert turn_angle(1.0, SETTINGS) == pytest.approx(0.2)
    assert turn_angle(5.0, SETTINGS) == pytest.approx(1.0)
    assert turn_angle(rise, SETTINGS) == pytest.approx(cap)
    assert turn_angle(rise + 1.0, SETTINGS) == pytest.approx(cap - 0.2)
    assert turn_angle(2.0 * rise, SETTINGS) == pytest.approx(0.0, abs=1e-12)
    assert turn_angle(2.0 * rise + 1.0, SETTINGS) == pytest.approx(0.2)
    durations = np.linspace(0.0, 100.0, 1001)
    angles = [turn_angle(duration, SETTINGS) for duration in durations]
    assert min(angles) >= 0.0 and max(angles) == pytest.approx(cap, abs=0.02)
    assert max(angles) <= cap + 1e-12


def test_a_turn_to_the_right_is_clockwise_and_keeps_the_speed():
    np.testing.assert_allclose(turned_right(EAST, math.pi / 2.0), [0.0, -1.0], atol=1e-15)
    turned = turned_right(np.array([0.0, 2.0]), math.pi / 3.0)
    np.testing.assert_allclose(turned, [math.sqrt(3.0), 1.0])
    assert np.hypot(*turned) == pytest.approx(2.0)


def test_a_stalled_robot_turns_right_more_and_more_then_returns_on_progress():
    escalation = Escalation()
    angles = []
    for time in np.arange(10.0, 15.05, 0.1):
        v = escalation.preferred(EAST, status(time, 10.0), SETTINGS)
        angles.append(-math.atan2(v[1], v[0]))
        assert np.hypot(*v) == pytest.approx(1.0)
        assert escalation.angle == pytest.approx(angles[-1])
    assert angles[0] == 0.0
    assert np.all(np.diff(angles) > 0.0)
    assert angles[10] == pytest.approx(0.2)  # 1 s into the stall
    assert angles[-1] == pytest.approx(1.0)
    # Progress ends the stall: back to the goal at once, the very array given.
    assert escalation.preferred(EAST, status(15.1, None), SETTINGS) is EAST
    assert escalation.angle == 0.0
    # The next stall starts from no turn.
    np.testing.assert_allclose(escalation.preferred(EAST, status(30.0, 30.0), SETTINGS), EAST)


def test_off_the_preference_is_never_turned():
    off = EscalationSettings(enabled=False)
    escalation = Escalation()
    for time in (10.0, 15.0, 100.0):
        assert escalation.preferred(EAST, status(time, 10.0), off) is EAST
        assert escalation.angle == 0.0
    assert turn_angle(100.0, off) == 0.0


def test_nothing_turns_without_a_stall_status_or_a_preference():
    escalation = Escalation()
    assert escalation.preferred(EAST, None, SETTINGS) is EAST
    standing = np.zeros(2)
    assert escalation.preferred(standing, status(20.0, 10.0), SETTINGS) is standing


def test_among_walls_the_robot_turns_only_with_room_on_its_right_decided_once_per_stall():
    asked = []

    def no_room(right):
        asked.append(right)
        return False

    escalation = Escalation()
    for time in (10.0, 12.0, 14.0):
        assert escalation.preferred(EAST, status(time, 10.0), SETTINGS, no_room) is EAST
    # Asked once, for the direction to the right of the preference.
    assert len(asked) == 1
    np.testing.assert_allclose(asked[0], [0.0, -1.0])
    # A new stall asks again; with room it turns.
    turned = escalation.preferred(EAST, status(25.0, 20.0), SETTINGS, lambda right: True)
    np.testing.assert_allclose(turned, turned_right(EAST, 1.0))

