"""The constant-velocity tracker against hand-derived prediction and simulated ground truth."""

import numpy as np
import pytest

from prvo_planner.estimation import (
    ConstantVelocityTracker,
    TrackFault,
    _process_noise,
    _transition,
)


def _hand_prediction(mean, covariance, dt, acceleration_std):
    """F x and F P F' + Q written out: per axis a velocity step of std acceleration_std * dt."""
    transition = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    step_variance = (acceleration_std * dt) ** 2
    per_axis = step_variance * np.array([[dt ** 2, dt], [dt, 1.0]])
    process = np.zeros((4, 4))
    for axis in (0, 1):
        index = [axis, axis + 2]
        process[np.ix_(index, index)] = per_axis
    return transition @ mean, transition @ covariance @ transition.T + process


def test_first_measurement_initialises_the_state():
    tracker = ConstantVelocityTracker(acceleration_std=0.5)
    covariance = np.diag([0.01, 0.02, 0.03, 0.04])
    tracker.update(2.0, [1.0, 2.0], [0.5, -0.5], covariance)
    belief = tracker.belief_at(2.0)
    np.testing.assert_allclose(belief.mean, [1.0, 2.0, 0.5, -0.5])
    np.testing.assert_allclose(belief.covariance, covariance, atol=1e-7)


def test_prediction_matches_the_hand_derived_model_and_grows_when_stale():
    rng = np.random.default_rng(3)
    tracker = ConstantVelocityTracker(acceleration_std=0.7)
    factor = rng.normal(size=(4, 4))
    covariance = factor @ factor.T * 0.01 + 0.001 * np.eye(4)
    tracker.update(0.0, [0.3, -0.2], [1.0, 0.4], covariance)
    filtered = tracker.belief_at(0.0)
    for dt in (0.1, 0.5, 2.0):
        predicted = tracker.belief_at(dt)
        mean, expected = _hand_prediction(filtered.mean, filtered.covariance, dt, 0.7)
        np.testing.assert_allclose(predicted.mean, mean, rtol=1e-12)
        np.testing.assert_allclose(predicted.covariance, expected, rtol=1e-10, atol=1e-14)
    # Stale data grows uncertain instead of being trusted, and asking does not change the filter.
    stale, fresh = tracker.belief_at(3.0), tracker.belief_at(1.0)
    assert np.trace(stale.covariance) > np.trace(fresh.covariance)
    np.testing.assert_allclose(tracker.belief_at(0.0).covariance, filtered.covariance)


def test_stamps_must_move_forward():
    tracker = ConstantVelocityTracker(acceleration_std=1.0)
    tracker.update(1.0, [0.0, 0.0], [0.0, 0.0], np.eye(4) * 0.01)
    with pytest.raises(ValueError, match='not after'):
        tracker.update(1.0, [0.0, 0.0], [0.0, 0.0], np.eye(4) * 0.01)
    with pytest.raises(ValueError, match='not after'):
        tracker.update(0.5, [0.0, 0.0], [0.0, 0.0], np.eye(4) * 0.01)


@pytest.mark.parametrize('acceleration_std', [0.5, 2.0])
def test_filter_is_consistent_on_simulated_targets(acceleration_std):
    """The normalised estimation error squared (NEES) averages the state dimension, 4.

    Targets move as a commanded base does and as the simulator integrates: the velocity steps at
    the start of each interval and the position moves the interval with the new velocity. A
    filter that gives the position too little process noise fails this (the constant-acceleration
    discretisation: mean NEES about 7.9 at acceleration_std 2).
    """
    rng = np.random.default_rng(11)
    dt, steps, runs = 0.1, 60, 400
    measurement_std = np.array([0.05, 0.05, 0.05, 0.05])
    nees = []
    for _ in range(runs):
        tracker = ConstantVelocityTracker(acceleration_std)
        state = np.concatenate([rng.uniform(-5, 5, 2), rng.uniform(-1, 1, 2)])
        for step in range(steps):
            if step:
                velocity = state[2:] + rng.normal(0.0, acceleration_std * dt, 2)
                state = np.concatenate([state[:2] + velocity * dt, velocity])
            measured = state + rng.normal(0.0, measurement_std)
            tracker.update(step * dt, measured[:2], measured[2:], np.diag(measurement_std ** 2))
        belief = tracker.belief_at((steps - 1) * dt)
        error = belief.mean - state
        nees.append(error @ np.linalg.solve(belief.covariance, error))
    # The mean of 400 chi-squared(4) draws has std 0.14: a band of about 3 std each side.
    assert 3.6 < np.mean(nees) < 4.4, np.mean(nees)


def test_rejects_a_non_positive_process_noise():
    with pytest.raises(ValueError, match='acceleration_std'):
        ConstantVelocityTracker(0.0)


@pytest.mark.parametrize('far_stamp', [2.0 ** 31 - 1.0, 1.7e9])
def test_an_unfusable_measurement_leaves_the_track_as_it_was(far_stamp):
    """A jump of years makes the innovation covariance numerically singular: refused, kept."""
    rng = np.random.default_rng(5)
    measurements = [(0.1 * step, rng.normal(size=2), rng.normal(size=2)) for step in range(4)]
    covariance = np.eye(4) * 0.0025
    tracker, reference = ConstantVelocityTracker(1.0), ConstantVelocityTracker(1.0)
    for stamp, position, velocity in measurements[:3]:
        tracker.update(stamp, position, velocity, covariance)
        reference.update(stamp, position, velocity, covariance)
    with pytest.raises(TrackFault, match='fails'):
        tracker.update(far_stamp, [0.0, 0.0], [0.0, 0.0], covariance)
    assert tracker.stamp == reference.stamp
    # The track goes on exactly as one that never saw the fault.
    stamp, position, velocity = measurements[3]
    tracker.update(stamp, position, velocity, covariance)
    reference.update(stamp, position, velocity, covariance)
    expected, actual = reference.belief_at(0.35), tracker.belief_at(0.35)
    np.testing.assert_array_equal(actual.mean, expected.mean)
    np.testing.assert_array_equal(actual.covariance, expected.covariance)


def test_the_filter_is_filterpys_kalman_filter_to_the_bit():
    """Every fused and predicted belief equals filterpy's KalmanFilter given the same models.

    The tracker writes the two Kalman steps out (importing filterpy costs a node about a second
    of start-up); filterpy is the independent implementation it must reproduce exactly, so that
    no plan moves. The models F and Q themselves are checked against the hand derivation above.
    """
    from filterpy.kalman import KalmanFilter, predict

    rng = np.random.default_rng(11)
    tracker = ConstantVelocityTracker(acceleration_std=0.8)
    reference = KalmanFilter(dim_x=4, dim_z=4)
    reference.H = np.eye(4)
    stamp, dt = 0.0, None
    for _ in range(200):
        factor = rng.normal(size=(4, 4)) * 0.05
        covariance = factor @ factor.T + 1e-4 * np.eye(4)
        measurement = np.concatenate([rng.normal(size=2) * 3.0, rng.normal(size=2)])
        tracker.update(stamp, measurement[:2], measurement[2:], covariance)
        noise = covariance + 1e-8 * np.eye(4)
        if dt is None:
            reference.x, reference.P = measurement, noise
        else:
            reference.predict(F=_transition(dt), Q=_process_noise(dt, 0.8))
            reference.update(measurement, R=noise)
        belief = tracker.belief_at(stamp)
        np.testing.assert_array_equal(belief.mean, reference.x)
        np.testing.assert_array_equal(belief.covariance, reference.P)
        dt = float(rng.choice([0.05, 0.1, 0.37]))
        stamp = round(stamp + dt, 9)
        dt = round(stamp - tracker.stamp, 9)
    ahead = tracker.belief_at(tracker.stamp + 0.25)
    mean, covariance = predict(reference.x, reference.P, F=_transition(0.25),
                               Q=_process_noise(0.25, 0.8))
    np.testing.assert_array_equal(ahead.mean, mean)
    np.testing.assert_array_equal(ahead.covariance, 0.5 * (covariance + covariance.T))
