"""
Occupancy grids, ROS-free: the map as the planner and the simulator both hold it.

The grid follows ``nav_msgs/OccupancyGrid``: row-major cells, row 0 at the bottom (smallest y),
``origin`` the world position of cell (0, 0)'s outer corner, values 0-100 (occupancy
probability in percent) or -1 (unknown).

The planner sees a grid as obstacles: the exact boundary between its occupied and free cells,
merged into maximal straight segments (``grid_obstacles``), kept in uniform buckets
(``ObstacleIndex``) so that finding those near a robot costs little on a large map.
"""

from dataclasses import dataclass
import math

import numpy as np

from prvo_planner.core.obstacles import StaticObstacles

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


# Bounds on the work that building a map's route (`route.RouteMap`) derives from the message
# besides its cells: the distance pass (`route.obstacle_distances`) pads the grid by the
# route's reach (clearance + margin, in cells) on every side and takes a minimum over as many
# offsets along each axis. At about 5 ns a visit, 2e9 visits are some 10 s of one core; the
# padded cells cost about 5 bytes each (a flag and an int32). A 4000 x 4000 map of 0.05 m cells
# with a reach of 1 m needs 1.6e7 padded cells and 1.3e9 visits.
MAX_PADDED_CELLS = 25_000_000
MAX_DISTANCE_VISITS = 2_000_000_000


class MapTooLargeError(ValueError):
    """A map whose route would take more memory or work than the bounds above allow."""


def check_route_work(shape, resolution, reach):
    """
    Raise MapTooLargeError if a route on a grid would need more than the bounds allow.

    Checked in constant time, before anything is allocated: the route of a grid of SHAPE
    (height, width) cells of RESOLUTION [m] keeping REACH [m] from obstacles pads the grid by
    w = REACH / RESOLUTION cells (rounded) on every side, to (height + 2w) (width + 2w) cells
    (at most ``MAX_PADDED_CELLS``), and visits (2w + 1) ((height + 2w) width + height width)
    cells (at most ``MAX_DISTANCE_VISITS``).
    """
    height, width = shape
    cells = reach / resolution
    # Exact integers, however large; cells of 1e-320 m make an infinite window.
    window = math.floor(cells + 0.5) if math.isfinite(cells) else math.inf
    padded = (height + 2 * window) * (width + 2 * window)
    visits = (2 * window + 1) * ((height + 2 * window) * width + height * width)
    if padded > MAX_PADDED_CELLS or visits > MAX_DISTANCE_VISITS:
        raise MapTooLargeError(
            f'{width} x {height} cells of {resolution:g} m: the route keeps {reach:g} m from '
            f'obstacles, {cells:.3g} cells, which asks for {padded:.3g} cells padded (at most '
            f'{MAX_PADDED_CELLS:.3g}) and {visits:.3g} cell visits (at most '
            f'{MAX_DISTANCE_VISITS:.3g})')


# A cell holding at least this occupancy [%] is occupied: map_server's default occupied_thresh
# (0.65), so that a map it serves in 'scale' mode reads as it does in 'trinary' mode (0, 100).
OCCUPIED_THRESHOLD = 65


def occupied_cells(grid, unknown_is_occupied=True):
    """
    Return which cells of a grid are obstacles.

    A cell is occupied when its value is at least ``OCCUPIED_THRESHOLD`` (65 %), or when it is
    unknown (-1) and ``unknown_is_occupied``; every other cell (0-64) is free.

    Parameters
    ----------
    grid : GridMap
        The map.
    unknown_is_occupied : bool
        Whether unknown cells are obstacles.

    Returns
    -------
    numpy.ndarray
        Shape (height, width), bool.

    """
    cells = grid.cells
    occupied = cells >= OCCUPIED_THRESHOLD
    if unknown_is_occupied:
        occupied |= cells == UNKNOWN
    return occupied


def occupied_at(occupied, resolution, origin, position):
    """Whether POSITION (2,) [m] lies in an occupied cell (off the grid: no)."""
    height, width = occupied.shape
    column, row = np.floor((np.asarray(position) - origin) / resolution).astype(int)
    return bool(0 <= row < height and 0 <= column < width and occupied[row, column])


def way_out(occupied, resolution, origin, position, reach):
    """
    Return where a robot whose centre is in an occupied cell gets out: the nearest free cell.

    The centre (2,) of the free cell nearest POSITION (2,) [m] within REACH [m], searched in
    the square window of that half-width around POSITION's cell; None when no free cell is that
    near. A map can mark the robot's own cells (a mapper that saw the robot, a map shifted
    under it): the way out is the shortest one. OCCUPIED (height, width) bool, RESOLUTION [m]
    and ORIGIN (2,) [m] as in `GridMap`.
    """
    height, width = occupied.shape
    column, row = np.floor((np.asarray(position) - origin) / resolution).astype(int)
    span = int(math.ceil(reach / resolution))
    rows = slice(max(row - span, 0), min(row + span + 1, height))
    columns = slice(max(column - span, 0), min(column + span + 1, width))
    free_rows, free_columns = np.nonzero(~occupied[rows, columns])
    if free_rows.size == 0:
        return None
    centres = origin + resolution * (np.stack([free_columns + columns.start,
                                               free_rows + rows.start], axis=1) + 0.5)
    distances = np.hypot(*(centres - position).T)
    nearest = int(np.argmin(distances))
    return centres[nearest] if distances[nearest] <= reach else None


def _runs(edges):
    """
    Return the maximal runs of True along the rows of EDGES (L, C), bool.

    Returns (line, first, end): the line index of each run, its first index and one past its
    last, each shape (R,), lines in order, runs in order along each line.
    """
    lines, length = edges.shape
    padded = np.zeros((lines, length + 2), dtype=bool)
    padded[:, 1:-1] = edges
    change = np.diff(padded.astype(np.int8), axis=1)
    start_lines, firsts = np.nonzero(change == 1)
    _, ends = np.nonzero(change == -1)
    return start_lines, firsts, ends


def boundary_segments(occupied, resolution, origin):
    """
    Return the exact boundary between occupied and free cells as segments.

    Every cell edge with an occupied cell on one side and a free one on the other is part of
    the boundary; the map's outside counts as occupied, so the border of free cells is too.
    Collinear edges that touch are merged into one maximal segment. Horizontal segments come
    first (by row line, then x), then vertical ones (by column line, then y).

    Parameters
    ----------
    occupied : numpy.ndarray
        Shape (height, width), bool: ``occupied[row, column]``, row 0 at the smallest y.
    resolution : float
        Cell edge [m].
    origin : array_like
        Shape (2,): world position of cell (0, 0)'s lower-left corner [m].

    Returns
    -------
    numpy.ndarray
        Shape (N, 2, 2): ``[[ax, ay], [bx, by]]`` [m], ``a`` the end of smaller coordinate.

    """
    occupied = np.asarray(occupied, dtype=bool)
    origin = np.asarray(origin, dtype=float)
    padded = np.pad(occupied, 1, constant_values=True)
    # Horizontal line j (y = origin_y + j * resolution, j = 0..height) separates rows j - 1
    # and j; vertical line i likewise columns i - 1 and i.
    horizontal = padded[:-1, 1:-1] != padded[1:, 1:-1]
    vertical = padded[1:-1, :-1] != padded[1:-1, 1:]
    lines, firsts, ends = _runs(horizontal)
    along_x = np.stack([
        np.stack([origin[0] + firsts * resolution, origin[1] + lines * resolution], axis=1),
        np.stack([origin[0] + ends * resolution, origin[1] + lines * resolution], axis=1)],
        axis=1)
    lines, firsts, ends = _runs(vertical.T)
    along_y = np.stack([
        np.stack([origin[0] + lines * resolution, origin[1] + firsts * resolution], axis=1),
        np.stack([origin[0] + lines * resolution, origin[1] + ends * resolution], axis=1)],
        axis=1)
    return np.concatenate([along_x.reshape(-1, 2, 2), along_y.reshape(-1, 2, 2)])


def grid_obstacles(grid, unknown_is_occupied=True):
    """
    Return the obstacles of a grid: its occupied cells' exact boundary, walls of no thickness.

    Parameters
    ----------
    grid : GridMap
        The map.
    unknown_is_occupied : bool
        Whether unknown cells are obstacles (see ``occupied_cells``).

    Returns
    -------
    StaticObstacles
        The segments of ``boundary_segments``, half-widths 0, no discs.

    """
    segments = boundary_segments(occupied_cells(grid, unknown_is_occupied), grid.resolution,
                                 grid.origin)
    return StaticObstacles(segments, np.zeros(len(segments)), np.zeros((0, 2)), np.zeros(0))


def _point_segment_distances(point, starts, ends):
    """Return the distances (N,) from POINT (2,) to the segments from STARTS to ENDS (N, 2)."""
    steps = ends - starts
    lengths_squared = np.einsum('ij,ij->i', steps, steps)
    fractions = np.clip(np.einsum('ij,ij->i', point - starts, steps) / lengths_squared, 0.0, 1.0)
    return np.linalg.norm(starts + fractions[:, None] * steps - point, axis=1)


# The most buckets an ObstacleIndex makes.
MAX_BUCKETS = 1 << 18


class ObstacleIndex:
    """
    Static obstacles in uniform square buckets, to find those near a position quickly.

    Each shape goes into every bucket its bounding box overlaps; a query looks at the buckets
    the query's square overlaps and keeps the shapes truly within the distance. The cost of a
    query grows with the shapes nearby, not with the size of the map.

    Parameters
    ----------
    obstacles : StaticObstacles
        Every obstacle.
    bucket_size : float
        Edge of a bucket [m], positive: about the usual query distance. Larger where the
        obstacles' extent would need more than ``MAX_BUCKETS`` buckets.

    """

    def __init__(self, obstacles, bucket_size):
        bucket_size = float(bucket_size)
        if not (np.isfinite(bucket_size) and bucket_size > 0.0):
            raise ValueError(f'bucket_size must be a positive number of metres, got '
                             f'{bucket_size!r}')
        self.obstacles = obstacles
        segments = obstacles.segments
        reach = obstacles.half_widths
        lows = np.concatenate([segments.min(axis=1) - reach[:, None],
                               obstacles.disc_centres - obstacles.disc_radii[:, None]])
        highs = np.concatenate([segments.max(axis=1) + reach[:, None],
                                obstacles.disc_centres + obstacles.disc_radii[:, None]])
        self._corner = lows.min(axis=0) if len(lows) else np.zeros(2)
        extent = (highs.max(axis=0) - self._corner) if len(lows) else np.zeros(2)
        # Few enough buckets for any distance asked for: memory stays bounded.
        self.bucket_size = max(bucket_size, float(np.sqrt(np.prod(extent + bucket_size)
                                                          / MAX_BUCKETS)))
        first = self._bucket_of(lows)
        last = self._bucket_of(highs)
        self._buckets_shape = (last.max(axis=0) + 1) if len(lows) else np.ones(2, dtype=int)
        shapes, buckets = [], []
        for shape, (low, high) in enumerate(zip(first, last, strict=True)):
            columns, rows = np.meshgrid(np.arange(low[0], high[0] + 1),
                                        np.arange(low[1], high[1] + 1))
            flat = (rows * self._buckets_shape[0] + columns).ravel()
            buckets.append(flat)
            shapes.append(np.full(len(flat), shape))
        buckets = np.concatenate(buckets) if buckets else np.zeros(0, dtype=int)
        shapes = np.concatenate(shapes) if shapes else np.zeros(0, dtype=int)
        order = np.argsort(buckets, kind='stable')
        # Bucket b holds the shapes self._members[self._offsets[b]:self._offsets[b + 1]].
        self._members = shapes[order]
        self._offsets = np.searchsorted(
            buckets[order], np.arange(int(np.prod(self._buckets_shape)) + 1))

    def _bucket_of(self, points):
        """Return the (column, row) bucket indices (P, 2) of POINTS (P, 2), unclipped."""
        return np.floor((points - self._corner) / self.bucket_size).astype(int)

    def near(self, position, distance):
        """
        Return the obstacles within a distance of a position.

        Parameters
        ----------
        position : array_like
            Shape (2,) [m].
        distance : float
            Largest distance [m] from ``position`` to a shape's surface (a segment's capsule of
            its half-width, a disc's rim) for the shape to count.

        Returns
        -------
        StaticObstacles
            Those shapes, segments and discs each in the order of ``obstacles``.

        """
        position = np.asarray(position, dtype=float)
        obstacles = self.obstacles
        low = np.maximum(self._bucket_of((position - distance)[None])[0], 0)
        high = np.minimum(self._bucket_of((position + distance)[None])[0],
                          self._buckets_shape - 1)
        if (low > high).any():
            return StaticObstacles.empty()
        rows = np.arange(low[1], high[1] + 1)
        starts = self._offsets[rows * self._buckets_shape[0] + low[0]]
        stops = self._offsets[rows * self._buckets_shape[0] + high[0] + 1]
        candidates = np.unique(np.concatenate(
            [self._members[start:stop] for start, stop in zip(starts, stops, strict=True)]))
        count = len(obstacles.segments)
        segments = candidates[candidates < count]
        discs = candidates[candidates >= count] - count
        chosen = obstacles.segments[segments]
        segments = segments[_point_segment_distances(position, chosen[:, 0], chosen[:, 1])
                            - obstacles.half_widths[segments] <= distance]
        discs = discs[np.linalg.norm(obstacles.disc_centres[discs] - position, axis=1)
                      - obstacles.disc_radii[discs] <= distance]
        return obstacles.subset(segments, discs)
