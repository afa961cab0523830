"""
Progress towards the goal over a window of time, and the detour of a robot that stalls.

A robot whose distance to its goal shrank by less than a fraction of what it could have covered
over the window is *stalled* (queued behind a jam, or circling). Its response is a rule every
robot applies the same way: it prefers, for as long as it stalls, a velocity turned clockwise
by a fixed angle from the way to the goal (a detour to the right). Robots jammed against each
other then circulate the same way round, as a roundabout, instead of each waiting for the
other. Only the preferred velocity changes: the constraints, and so the set of velocities a
plan may choose from, are untouched.
"""

from collections import deque
import math

import numpy as np


class ProgressWindow:
    """
    Distances to the goal of the last ``window`` seconds of plans.

    Parameters
    ----------
    window : float
        Length of the window, seconds, > 0.

    """

    def __init__(self, window):
        if not window > 0.0:
            raise ValueError(f'window must be > 0, got {window!r}')
        self.window = float(window)
        self._samples = deque()

    def clear(self):
        """Forget every sample (a new goal)."""
        self._samples.clear()

    def add(self, stamp, distance):
        """Record the DISTANCE [m] to the goal at STAMP [s]; stamps must not decrease."""
        if self._samples and stamp < self._samples[-1][0]:
            raise ValueError(f'stamp {stamp!r} is before the last one {self._samples[-1][0]!r}')
        self._samples.append((float(stamp), float(distance)))
        # Keep the newest sample at or before the window's start: the progress is measured
        # from there.
        while len(self._samples) > 1 and self._samples[1][0] <= stamp - self.window:
            self._samples.popleft()

    def progress(self):
        """
        Return (progress [m], elapsed [s], distance at the start [m]) over the window.

        None before the samples span the window. Progress is how much the distance to the goal
        shrank from the window's start to the newest sample (negative when it grew).
        """
        if not self._samples:
            return None
        (start, first), (end, last) = self._samples[0], self._samples[-1]
        if end - start < self.window:
            return None
        return first - last, end - start, first


def stalled(window, max_speed, min_progress, goal_tolerance):
    """
    Whether the robot stalls: its progress over WINDOW is below MIN_PROGRESS of what it can do.

    What it can do is ``max_speed * elapsed``, but no more than the distance it had left to
    the goal's tolerance at the window's start (near the goal it slows down by design). Never
    stalled before the window is full.
    """
    measured = window.progress()
    if measured is None:
        return False
    progress, elapsed, start_distance = measured
    possible = min(max_speed * elapsed, start_distance - goal_tolerance)
    return possible > 0.0 and progress < min_progress * possible


def detour(v_pref, angle):
    """Return V_PREF (2,) turned clockwise (to the right) by ANGLE [rad]."""
    cosine, sine = math.cos(angle), math.sin(angle)
    return np.array([cosine * v_pref[0] + sine * v_pref[1],
                     -sine * v_pref[0] + cosine * v_pref[1]])
