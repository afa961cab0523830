"""Metrics against hand-built ground truth whose contacts, separations and arrivals are known."""

import math

import numpy as np
import pytest

from prvo_sim import metrics

DT = 0.1
TIMES = np.round(np.arange(0.0, 4.0 + DT / 2, DT), 10)


def crossing_ground_truth():
    """Return three robots: A and B pass through each other on the x axis, C passes its goal.

    A: x = -2 + t, B: x = 2 - t (y = 0), radii 0.25: centre distance |4 - 2t| < 0.5 exactly for
    t in (1.75, 2.25), so one contact entered at the sample t = 1.8, and the minimum separation
    is 0 - 0.5 at t = 2. C: (0, 3 + t), goal (0, 4.5): inside the 0.2 tolerance for t in
    [1.3, 1.7], then gone. A's goal (1.85, 0) is within 0.2 from t = 3.65 on (first sample 3.7).
    """
    positions = np.zeros((TIMES.size, 3, 2))
    positions[:, 0, 0] = -2.0 + TIMES
    positions[:, 1, 0] = 2.0 - TIMES
    positions[:, 2, 1] = 3.0 + TIMES
    radii = np.array([0.25, 0.25, 0.25])
    goals = np.array([[1.85, 0.0], [-1.85, 0.0], [0.0, 4.5]])
    return positions, radii, goals


def test_contact_events_count_each_entry_of_a_pair_once():
    positions, radii, _ = crossing_ground_truth()
    events = metrics.contact_events(TIMES, positions, radii)
    assert len(events) == 1
    contact_time, first, second, distance = events[0]
    assert (first, second) == (0, 1)
    assert contact_time == pytest.approx(1.8)
    assert distance == pytest.approx(4.0 - 2.0 * 1.8)


def test_a_pair_that_leaves_and_reenters_contact_counts_twice():
    # Centre distances 1.0, 0.4, 0.4, 1.0, 0.3, 1.0 against a sum of radii of 0.5.
    distances = np.array([1.0, 0.4, 0.4, 1.0, 0.3, 1.0])
    positions = np.zeros((distances.size, 2, 2))
    positions[:, 1, 0] = distances
    times = np.arange(distances.size) * DT
    events = metrics.contact_events(times, positions, [0.2, 0.3])
    assert [(round(event[0], 6), event[1], event[2]) for event in events] == [
        (0.1, 0, 1), (0.4, 0, 1)]
    assert metrics.min_separation(positions, [0.2, 0.3]) == pytest.approx(0.3 - 0.5)


def test_contact_at_the_first_sample_counts():
    positions = np.array([[[0.0, 0.0], [0.1, 0.0]], [[0.0, 0.0], [2.0, 0.0]]])
    assert len(metrics.contact_events([0.0, 0.1], positions, [0.3, 0.3])) == 1


def test_pairwise_separation_matches_distance_minus_radii():
    positions, radii, _ = crossing_ground_truth()
    separations = metrics.pairwise_separation(positions, radii)
    # Pairs in order (0, 1), (0, 2), (1, 2).
    assert separations.shape == (TIMES.size, 3)
    np.testing.assert_allclose(separations[:, 0], np.abs(4.0 - 2.0 * TIMES) - 0.5, atol=1e-12)
    expected_ac = np.hypot(-2.0 + TIMES, 3.0 + TIMES) - 0.5
    np.testing.assert_allclose(separations[:, 1], expected_ac, atol=1e-12)
    assert metrics.min_separation(positions, radii) == pytest.approx(-0.5)


def test_arrival_is_the_first_step_at_the_goal_also_for_a_robot_pushed_aside_later():
    # Along x towards a goal at 0 with tolerance 0.2: in (index 1), out, in again, stays; a
    # robot at its goal keeps planning and may step aside, so its first arrival counts.
    positions = np.array([[[1.0, 0.0]], [[0.1, 0.0]], [[1.0, 0.0]], [[0.1, 0.0]],
                          [[0.05, 0.0]]])
    assert metrics.arrival_indices(positions, [[0.0, 0.0]], 0.2) == [1]
    # Arrived, then pushed aside at the end of the run: still arrived, at its first arrival.
    assert metrics.arrival_indices(positions[::-1], [[0.0, 0.0]], 0.2) == [0]
    assert metrics.arrival_indices(positions[[0, 2]], [[0.0, 0.0]], 0.2) == [None]
    run = metrics.run_metrics(np.arange(5) * 0.5, positions, [0.3], [[0.0, 0.0]], 0.2, ['a'])
    assert run['robots']['a'] == {'arrived': True, 'time_to_goal': 0.5, 'path_length': 0.9,
                                  'scripted': False}


def test_run_metrics_of_the_hand_built_run():
    positions, radii, goals = crossing_ground_truth()
    result = metrics.run_metrics(TIMES, positions, radii, goals, 0.2, ['a', 'b', 'c'])
    assert result['robots']['a'] == {'arrived': True, 'time_to_goal': pytest.approx(3.7),
                                     'path_length': pytest.approx(3.7), 'scripted': False}
    assert result['robots']['b']['time_to_goal'] == pytest.approx(3.7)
    # C passed through its goal and left: it arrived at its first sample within tolerance
    # (4.4 at t = 1.4; 4.3 lies a rounding error outside), its path running up to there.
    assert result['robots']['c'] == {'arrived': True, 'time_to_goal': pytest.approx(1.4),
                                     'path_length': pytest.approx(1.4), 'scripted': False}
    assert result['success_rate'] == 1.0
    assert result['collisions'] == 1
    assert result['min_separation'] == pytest.approx(-0.5)
    assert result['makespan'] == pytest.approx(3.7)
    assert result['mean_time_to_goal'] == pytest.approx((3.7 + 3.7 + 1.4) / 3)
    assert result['sim_time'] == pytest.approx(4.0)


def test_a_robot_never_at_its_goal_has_not_arrived():
    positions, radii, goals = crossing_ground_truth()
    goals[2] = [1.0, 4.5]  # C passes 1 m from it
    result = metrics.run_metrics(TIMES, positions, radii, goals, 0.2, ['a', 'b', 'c'])
    assert result['robots']['c'] == {'arrived': False, 'time_to_goal': None,
                                     'path_length': pytest.approx(4.0), 'scripted': False}
    assert result['success_rate'] == pytest.approx(2.0 / 3.0)
    assert result['makespan'] is None
    assert result['scripted_robots'] == []


def test_makespan_is_the_last_arrival_when_all_arrive():
    positions, radii, goals = crossing_ground_truth()
    goals[2] = [0.0, 6.85]  # C is within 0.2 of it from t = 3.65 on, at 7.0 at the end
    result = metrics.run_metrics(TIMES + 5.0, positions, radii, goals, 0.2, ['a', 'b', 'c'])
    assert result['makespan'] == pytest.approx(3.7)
    assert result['success_rate'] == 1.0


def test_distribution_summary_of_one_to_hundred():
    summary = metrics.distribution_summary(np.arange(1, 101))
    # Linear interpolation: the 95th percentile of 1..100 lies at 1 + 0.95 * 99.
    assert summary == {'median': 50.5, 'p95': pytest.approx(95.05), 'max': 100.0}
    assert metrics.distribution_summary([]) == {'median': None, 'p95': None, 'max': None}


def test_aggregate_skips_missing_values_and_reaches_nested_keys():
    runs = [{'makespan': 10.0, 'planner_ms': {'median': 1.0}},
            {'makespan': None, 'planner_ms': {'median': 3.0}},
            {'makespan': 14.0, 'planner_ms': {'median': 2.0}}]
    summary = metrics.aggregate(runs, ['makespan', 'planner_ms.median', 'absent'])
    assert summary['makespan'] == {'mean': 12.0, 'std': 2.0, 'min': 10.0, 'max': 14.0, 'n': 2}
    assert summary['planner_ms.median']['mean'] == pytest.approx(2.0)
    assert summary['planner_ms.median']['std'] == pytest.approx(math.sqrt(2.0 / 3.0))
    assert summary['absent']['n'] == 0
