"""
Occupancy grids, ROS-free: the map as the planner and the simulator both hold it.

The grid follows ``nav_msgs/OccupancyGrid``: row-major cells, row 0 at the bottom (smallest y),
``origin`` the world position of cell (0, 0)'s outer corner, values 0-100 (occupancy
probability in percent) or -1 (unknown).
"""

from dataclasses import dataclass

import numpy as np

UNKNOWN = -1
OCCUPIED = 100
FREE = 0


@dataclass(frozen=True)
class GridMap:
    """
    An occupancy grid in the world frame, axis-aligned.

    Attributes
    ----------
    cells : numpy.ndarray
        Shape (height, width), int8: ``cells[row, column]`` is the cell whose lower-left corner
        is ``origin + resolution * (column, row)``; values -1 (unknown) or 0-100.
    resolution : float
        Cell edge [m], positive.
    origin : numpy.ndarray
        Shape (2,): world position of cell (0, 0)'s lower-left corner [m].

    """

    cells: np.ndarray
    resolution: float
    origin: np.ndarray

    def __post_init__(self):
        cells = np.array(self.cells)
        if cells.ndim != 2 or cells.size == 0:
            raise ValueError(f'cells must be a non-empty 2-D array, got shape {cells.shape}')
        if not np.issubdtype(cells.dtype, np.integer):
            raise ValueError(f'cells must be integers, got dtype {cells.dtype}')
        if ((cells < UNKNOWN) | (cells > OCCUPIED)).any():
            raise ValueError('cells must be -1 (unknown) or 0-100, got values from '
                             f'{int(cells.min())} to {int(cells.max())}')
        cells = cells.astype(np.int8)
        cells.setflags(write=False)
        resolution = float(self.resolution)
        if not np.isfinite(resolution) or resolution <= 0.0:
            raise ValueError(f'resolution must be a positive number of metres, got {resolution!r}')
        origin = np.array(self.origin, dtype=float)
        if origin.shape != (2,) or not np.isfinite(origin).all():
            raise ValueError(f'origin must be a finite (x, y) position, got {self.origin!r}')
        origin.setflags(write=False)
        object.__setattr__(self, 'cells', cells)
        object.__setattr__(self, 'resolution', resolution)
        object.__setattr__(self, 'origin', origin)

    @property
    def shape(self):
        """Return (height, width) in cells."""
        return self.cells.shape
