"""
Static obstacles as the planner sees them: wall segments and discs in the world frame.

A wall is a segment ``[a, b]`` with a half-width (half its thickness); a solid polygon is its
edges with half-width 0; an occupancy grid becomes the segments of its cells' boundary. A disc
is a static neighbour: known centre, zero velocity, no covariance of its own.
"""

from dataclasses import dataclass
import functools

import numpy as np

from .beliefs import as_finite_array


@dataclass(frozen=True)
class StaticObstacles:
    """
    Segments and discs that never move, in the world frame.

    Attributes
    ----------
    segments : numpy.ndarray
        Shape (N, 2, 2): ``segments[i] = [[ax, ay], [bx, by]]`` [m], ends distinct.
    half_widths : numpy.ndarray
        Shape (N,): half of each wall's thickness [m], at least 0.
    disc_centres : numpy.ndarray
        Shape (M, 2): centres of disc obstacles [m].
    disc_radii : numpy.ndarray
        Shape (M,): their radii [m], positive.

    """

    segments: np.ndarray
    half_widths: np.ndarray
    disc_centres: np.ndarray
    disc_radii: np.ndarray

    def __post_init__(self):
        segments = np.asarray(self.segments, dtype=float).reshape(-1, 2, 2)
        count = len(segments)
        discs = np.asarray(self.disc_centres, dtype=float).reshape(-1, 2)
        fields = {
            'segments': as_finite_array(segments, (count, 2, 2), 'segments'),
            'half_widths': as_finite_array(self.half_widths, (count,), 'half_widths'),
            'disc_centres': as_finite_array(discs, (len(discs), 2), 'disc_centres'),
            'disc_radii': as_finite_array(self.disc_radii, (len(discs),), 'disc_radii'),
        }
        lengths = np.linalg.norm(fields['segments'][:, 1] - fields['segments'][:, 0], axis=1)
        if (lengths <= 0.0).any():
            index = int(np.argmax(lengths <= 0.0))
            raise ValueError(f'segment {index} has two equal ends: '
                             f'{fields["segments"][index].tolist()!r}')
        if (fields['half_widths'] < 0.0).any():
            raise ValueError(f'half_widths must be >= 0, got {fields["half_widths"].tolist()!r}')
        if (fields['disc_radii'] <= 0.0).any():
            raise ValueError(f'disc_radii must be > 0, got {fields["disc_radii"].tolist()!r}')
        for name, value in fields.items():
            object.__setattr__(self, name, value)

    @classmethod
    def empty(cls):
        """Return the obstacles of an empty plane."""
        return cls(np.zeros((0, 2, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0))

    def subset(self, segments, discs):
        """
        Return the segments and discs at the given indices, each in the order given.

        The shapes were checked when this set was made, so the subset is not checked again (a
        map's index asks for one every plan: the checks were a third of its query), and its
        frames are this set's rows (the same numbers, computed row by row).

        Parameters
        ----------
        segments, discs : numpy.ndarray
            Integer indices into ``segments`` and into ``disc_centres``, shape (n,) and (q,).

        Returns
        -------
        StaticObstacles

        """
        subset = object.__new__(StaticObstacles)
        for name, value in (('segments', self.segments[segments]),
                            ('half_widths', self.half_widths[segments]),
                            ('disc_centres', self.disc_centres[discs]),
                            ('disc_radii', self.disc_radii[discs])):
            object.__setattr__(subset, name, value)
        frames = self.frames[segments]
        frames.setflags(write=False)
        # functools.cached_property keeps its value in the instance's __dict__.
        subset.__dict__['frames'] = frames
        return subset

    def __len__(self):
        """Return the number of shapes: segments plus discs."""
        return len(self.segments) + len(self.disc_radii)

    @functools.cached_property
    def frames(self):
        """
        Each segment's frame, computed once: shape (N, 6).

        Columns: the unit vector ``u`` along ``b - a`` (2), the unit vector across it,
        ``(-u_y, u_x)`` (2), ``u.a`` and ``u.b``.
        """
        start, end = self.segments[:, 0], self.segments[:, 1]
        along = end - start
        unit = along / np.hypot(along[:, 0], along[:, 1])[:, None]
        frames = np.empty((len(start), 6))
        frames[:, :2] = unit
        frames[:, 2] = -unit[:, 1]
        frames[:, 3] = unit[:, 0]
        frames[:, 4] = np.sum(unit * start, axis=1)
        frames[:, 5] = np.sum(unit * end, axis=1)
        frames.setflags(write=False)
        return frames
