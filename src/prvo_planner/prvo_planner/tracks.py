"""Tracks of robots fed by odometry: one filter per robot and the rules for their stamps.

A `TrackTable` holds a `ConstantVelocityTracker` per robot name and decides what each
measurement does to it (fused, a duplicate, stale, a restart after the source's time jumped).
It reads no clock: `now` is monotonic seconds of the caller's choosing. A planner agent owns
one for its neighbours; agents that receive the same measurements at the same `now` with the
same settings (a team in one process) can share one, so each robot is filtered once per step
instead of once per neighbour, with the same numbers.
"""

import dataclasses

from prvo_planner.core import AgentBelief
from prvo_planner.estimation import ConstantVelocityTracker, TrackFault

# A stamp this far behind a track's last one means its source restarted (e.g. the simulator):
# the track starts over instead of rejecting every message from then on.
TIME_RESET_SECONDS = 1.0
# A stamp this far ahead of a track's last one is a fault (a wall-clock stamp among sim-time
# ones, a garbage sec field), not motion: odometry comes at several Hz, over 10 s the prediction
# of 1 m/s^2 noise is already some 18 m wide, and over years its rounding breaks the filter.
MAX_STAMP_JUMP_SECONDS = 10.0


@dataclasses.dataclass(frozen=True)
class Fusion:
    """What became of one measurement.

    `status` is 'fused', 'restarted' or 'resumed' (accepted; 'restarted': its time went back, so
    the track started over; 'resumed': a new track of a robot dropped before), 'duplicate'
    (the stamp of the last accepted one), or a fault that left the track as it was: 'stale' (a
    little behind the last stamp), 'refused' (far ahead of it, or numerically unusable).
    `detail` says why, with the values.
    """

    status: str
    detail: str = ''

    @property
    def accepted(self):
        """Whether the measurement reached the track."""
        return self.status in ('fused', 'restarted', 'resumed')


class Track:
    """One tracked robot: its filter and when (caller's `now`) it last accepted a measurement.

    `superseded` is the track a backward time jump replaced, kept until the new time goes on.
    Beliefs predicted to a stamp are kept until the next measurement: every planner that
    shares the track asks for the same stamp.
    """

    def __init__(self, acceleration_std, now, superseded=None):
        self.tracker = ConstantVelocityTracker(acceleration_std)
        self.last_heard = now
        self.superseded = superseded
        self._beliefs = {}
        self._agent_beliefs = {}

    @property
    def stamp(self):
        """Stamp of the last accepted measurement [s]."""
        return self.tracker.stamp

    def fits(self, stamp):
        """Whether STAMP continues this track: later than its last, by a plausible step."""
        return 0.0 < stamp - self.tracker.stamp <= MAX_STAMP_JUMP_SECONDS

    def belief_at(self, stamp):
        """Return the tracker's `StateBelief` predicted to STAMP (kept until the next update)."""
        belief = self._beliefs.get(stamp)
        if belief is None:
            belief = self._beliefs[stamp] = self.tracker.belief_at(stamp)
        return belief

    def agent_belief(self, stamp, radius, avoidance_share):
        """Return the core's `AgentBelief` of this robot at STAMP (kept too).

        RADIUS [m] and AVOIDANCE_SHARE are what the robot announced.
        """
        key = (stamp, radius, avoidance_share)
        belief = self._agent_beliefs.get(key)
        if belief is None:
            state = self.belief_at(stamp)
            belief = self._agent_beliefs[key] = AgentBelief(
                state.mean[:2], state.mean[2:], state.covariance, radius, avoidance_share)
        return belief

    def update(self, measurement, now):
        """Feed MEASUREMENT to the filter (raises `TrackFault`, leaving it as it was)."""
        self.tracker.update(measurement.stamp, measurement.position, measurement.velocity,
                            measurement.covariance)
        self.last_heard = now
        self._beliefs.clear()
        self._agent_beliefs.clear()


def fuse(track, measurement, now, acceleration_std, neighbor_timeout):
    """Return (the track to keep, the `Fusion`) of MEASUREMENT fed to TRACK (None: new).

    `acceleration_std` is the filter noise of a track started here [m/s^2];
    `neighbor_timeout` [s of `now`] how long a silent track refuses a jump ahead before its
    source's time is taken to have moved on for good.
    """
    stamp = measurement.stamp
    if track is None:
        return _update(Track(acceleration_std, now), measurement, now, 'fused')
    last = track.stamp
    if track.superseded is not None and track.superseded.fits(stamp) and not track.fits(stamp):
        # A single stamp from the past replaced the track; time goes on from the old one.
        return _update(track.superseded, measurement, now, 'fused')
    if stamp == last:
        # The source is alive, repeating its state (a lockstep simulator re-sends t_0 until
        # every node is up): not silent, though nothing is fused.
        track.last_heard = now
        return track, Fusion('duplicate')
    if stamp < last:
        if last - stamp <= TIME_RESET_SECONDS:
            return track, Fusion(
                'stale', f'stamp {stamp:.3f} s is not after the last one ({last:.3f} s)')
        return _update(
            Track(acceleration_std, now, superseded=track), measurement, now, 'restarted',
            f'time jumped back from {last:.3f} s to {stamp:.3f} s: restarting the track')
    if stamp - last > MAX_STAMP_JUMP_SECONDS:
        if now - track.last_heard <= neighbor_timeout:
            return track, Fusion(
                'refused', f'stamp {stamp:.3f} s is more than {MAX_STAMP_JUMP_SECONDS:g} s '
                f'after the last one ({last:.3f} s)')
        # Nothing usable for a whole neighbour timeout: the source's time moved on for good.
        return _update(
            Track(acceleration_std, now), measurement, now, 'restarted',
            f'time jumped ahead from {last:.3f} s to {stamp:.3f} s after '
            f'{now - track.last_heard:.1f} s without a usable stamp: restarting the track')
    track.superseded = None
    return _update(track, measurement, now, 'fused')


def _update(track, measurement, now, status, detail=''):
    """Feed MEASUREMENT to TRACK; return (TRACK, Fusion(STATUS) or 'refused')."""
    try:
        track.update(measurement, now)
    except TrackFault as fault:
        return track, Fusion('refused', str(fault))
    return track, Fusion(status, detail)


class TrackTable:
    """The tracks of many robots, by name.

    Parameters
    ----------
    acceleration_std : float
        Filter noise of the tracks started from now on [m/s^2].
    neighbor_timeout : float
        Seconds (of `now`) of silence after which a track is dropped by `forget`.

    """

    def __init__(self, acceleration_std, neighbor_timeout):
        self.acceleration_std = acceleration_std
        self.neighbor_timeout = neighbor_timeout
        self._tracks = {}
        # Robots dropped for silence or absence: a new track of one of them is 'resumed'.
        self._dropped = set()
        # (stamp, names, tracks, beliefs) of every robot at the stamp last asked for, until a
        # track changes (`beliefs_at`).
        self._at = None

    def __contains__(self, robot):
        return robot in self._tracks

    def names(self):
        """Return the names of the robots tracked now (insertion order)."""
        return list(self._tracks)

    def track(self, robot):
        """Return ROBOT's `Track` (KeyError when it is not tracked)."""
        return self._tracks[robot]

    def beliefs_at(self, stamp, excluded=None):
        """Return (names, tracks, beliefs at STAMP) of the robots tracked now but EXCLUDED.

        Tuples in the table's order; the beliefs are the tracks' `belief_at(STAMP)`. Made once
        for the whole table until a track changes: the agents that share it plan for the same
        stamp, and each leaves out only itself.
        """
        if self._at is None or self._at[0] != stamp:
            tracks = tuple(self._tracks.values())
            self._at = (stamp, tuple(self._tracks), tracks,
                        tuple(track.belief_at(stamp) for track in tracks))
        _, names, tracks, beliefs = self._at
        if excluded not in self._tracks:
            return names, tracks, beliefs
        index = names.index(excluded)
        return tuple(values[:index] + values[index + 1:] for values in (names, tracks, beliefs))

    def receive(self, robot, measurement, now):
        """Fuse ROBOT's MEASUREMENT; return its `Fusion`."""
        self._at = None
        track, fusion = fuse(self._tracks.get(robot), measurement, now, self.acceleration_std,
                             self.neighbor_timeout)
        self._tracks[robot] = track
        if fusion.accepted and robot in self._dropped:
            self._dropped.discard(robot)
            return Fusion('resumed', f'tracking {robot} again from {measurement.stamp:.3f} s, '
                          'after it was dropped')
        return fusion

    def forget(self, now, wanted=None):
        """Drop robots silent longer than neighbor_timeout, or not in WANTED (if given).

        Returns [(robot, seconds silent)] of those dropped.
        """
        dropped = []
        self._at = None
        for robot, track in list(self._tracks.items()):
            silent = now - track.last_heard
            if (wanted is not None and robot not in wanted) or silent > self.neighbor_timeout:
                del self._tracks[robot]
                self._dropped.add(robot)
                dropped.append((robot, silent))
        return dropped
