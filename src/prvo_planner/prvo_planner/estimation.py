"""Constant-velocity tracking of a robot's planar state with a Kalman filter (docs/method.md 8).

Plain numpy, no ROS: the planner node feeds it measurements converted by prvo_msgs_util and asks
it for beliefs predicted to the planning time. The filter's two steps are filterpy's
`KalmanFilter` equations (the same operations in the same order, so the same numbers; the tests
check it against filterpy): importing filterpy would import scipy.stats, half of every node's
start-up time.
"""

from dataclasses import dataclass
import functools

import numpy as np

# Measurement covariances are floored so that an exact (zero-variance) odometry source does not
# make the innovation covariance singular.
_MEASUREMENT_VARIANCE_FLOOR = 1e-8
# Relative rounding allowed when checking that a posterior variance is at most the measurement's.
_POSTERIOR_SLACK = 1.0 + 1e-6


class TrackFault(ValueError):  # noqa: N818 (names the fault like MessageFault)
    """A measurement the filter cannot fuse; the track is left as it was."""


# Both models are cached by `dt`: odometry arrives at a fixed period, so a few values recur on
# every message of every robot. The cached arrays are read-only.
@functools.lru_cache(maxsize=64)
def _transition(dt):
    """Return F (4, 4) of the constant-velocity model over `dt` seconds, state [x, y, vx, vy]."""
    transition = np.eye(4)
    transition[0, 2] = transition[1, 3] = dt
    transition.flags.writeable = False
    return transition


@functools.lru_cache(maxsize=64)
def _process_noise(dt, acceleration_std):
    """Return Q (4, 4) over [x, y, vx, vy]: a velocity that changes at the start of each interval.

    Each axis's velocity changes once per interval by a white step of std
    `acceleration_std * dt`, and the position moves the whole interval with the new velocity:
    with `G = [dt, 1]`, `Q_axis = G G' (acceleration_std dt)^2`. That is how a base that
    executes each velocity command at once moves (and how the simulator integrates). The
    constant-acceleration discretisation (`G = [dt^2 / 2, dt]`) gives the position a quarter of
    that variance and left the beliefs of manoeuvring robots overconfident.
    """
    change = np.array([dt, 1.0])
    per_axis = np.outer(change, change) * (acceleration_std * dt) ** 2
    noise = np.zeros((4, 4))
    for axis in (0, 1):
        noise[np.ix_((axis, axis + 2), (axis, axis + 2))] = per_axis
    noise.flags.writeable = False
    return noise


def predict(state, covariance, transition, process_noise):
    """Return the prior (state (4,), covariance (4, 4)) one interval later.

    `x = F x`, `P = F P F' + Q` for the transition F (4, 4) and process noise Q (4, 4).
    """
    return (np.dot(transition, state),
            np.dot(np.dot(transition, covariance), transition.T) + process_noise)


def update(state, covariance, measurement, noise):
    """Return the posterior (state (4,), covariance (4, 4)) after a full-state measurement.

    The measurement z (4,) has covariance R (4, 4) and measures the state itself (H = I), so the
    innovation covariance is `S = P + R` and the gain `K = P S^-1`. The covariance update is
    Joseph's form, `(I - K) P (I - K)' + K R K'`, which stays symmetric and positive definite
    under rounding where the textbook `(I - K) P` may not.
    """
    gain = np.dot(covariance, np.linalg.inv(covariance + noise))
    complement = np.eye(4) - gain
    return (state + np.dot(gain, measurement - state),
            np.dot(np.dot(complement, covariance), complement.T)
            + np.dot(np.dot(gain, noise), gain.T))


@dataclass(frozen=True)
class StateBelief:
    """Gaussian belief over [x, y, vx, vy] at time `stamp`: `mean` (4,), `covariance` (4, 4)."""

    stamp: float
    mean: np.ndarray
    covariance: np.ndarray


class ConstantVelocityTracker:
    """A Kalman filter over [x, y, vx, vy] fed full-state measurements (`predict`, `update`).

    Parameters
    ----------
    acceleration_std : float
        How fast the velocity may change [m/s^2]: between measurements `dt` apart it steps by a
        white change of std `acceleration_std * dt` (`_process_noise`). It also makes a stale
        track's covariance grow.

    """

    def __init__(self, acceleration_std):
        if not acceleration_std > 0.0:
            raise ValueError(f'acceleration_std must be > 0, got {acceleration_std!r}')
        self.acceleration_std = float(acceleration_std)
        self._state = None  # (4,)
        self._covariance = None  # (4, 4)
        self._stamp = None

    @property
    def stamp(self):
        """Time of the last accepted measurement [s], or None before the first."""
        return self._stamp

    def update(self, stamp, position, velocity, covariance):
        """Fuse a measurement taken at `stamp` [s].

        Parameters
        ----------
        stamp : float
            Measurement time; must be later than the last accepted one.
        position, velocity : array_like, shape (2,)
            Measured mean position [m] and velocity [m/s] in the world frame.
        covariance : array_like, shape (4, 4)
            Measurement covariance over [x, y, vx, vy].

        Raises
        ------
        ValueError
            If `stamp` is not later than the last accepted measurement.
        TrackFault
            If fusing the measurement fails numerically (an innovation or posterior covariance
            that is not positive definite, a non-finite state); the filter keeps its state.

        """
        measurement = np.concatenate([position, velocity]).astype(float)
        noise = np.asarray(covariance, dtype=float) + _MEASUREMENT_VARIANCE_FLOOR * np.eye(4)
        if self._state is None:
            self._state, self._covariance = measurement, noise
            self._stamp = float(stamp)
            return
        dt = float(stamp) - self._stamp
        if not dt > 0.0:
            raise ValueError(
                f'stamp {stamp:.3f} s is not after the last measurement {self._stamp:.3f} s')
        # ROS stamps have nanosecond resolution: rounding there makes recurring periods equal.
        dt = round(dt, 9)
        prior_state, prior_covariance = predict(
            self._state, self._covariance, _transition(dt),
            _process_noise(dt, self.acceleration_std))
        try:
            # H is the identity: the innovation covariance is P + R.
            np.linalg.cholesky(prior_covariance + noise)
            state, covariance = update(prior_state, prior_covariance, measurement, noise)
            if not np.isfinite(state).all():
                raise np.linalg.LinAlgError('non-finite state')
            # A full-state measurement bounds the posterior: no variance can exceed the
            # measurement's. Rounding in a huge prediction breaks that (variances of 1e34 after
            # a jump of 1.7e9 s), and the result is no belief at all.
            if not (np.diag(covariance) <= _POSTERIOR_SLACK * np.diag(noise)).all():
                raise np.linalg.LinAlgError('posterior variance beyond the measurement variance')
        except np.linalg.LinAlgError as error:
            raise TrackFault(
                f'fusing a measurement {dt:g} s after the last one fails: {error}') from None
        self._state, self._covariance = state, covariance
        self._stamp = float(stamp)

    def belief_at(self, stamp):
        """Return the `StateBelief` predicted to `stamp` [s] without changing the filter.

        A `stamp` at or before the last measurement returns the filtered state as it is.
        """
        if self._state is None:
            raise RuntimeError('belief_at() before any measurement')
        dt = float(stamp) - self._stamp
        if dt <= 0.0:
            return StateBelief(self._stamp, self._state.copy(), self._covariance.copy())
        dt = round(dt, 9)
        mean, covariance = predict(self._state, self._covariance, _transition(dt),
                                   _process_noise(dt, self.acceleration_std))
        return StateBelief(float(stamp), mean, 0.5 * (covariance + covariance.T))
