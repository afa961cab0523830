"""
The way to a goal on an occupancy grid: the shortest path through cells a robot fits in, no ROS.

A cell is admissible when its centre keeps at least a clearance (the robot's radius) from every
occupied cell, the map's outside counting as occupied. Paths run between admissible cells'
centres on the 8-connected grid: a straight step costs one cell edge, a diagonal step
sqrt(2) of it and only where both cells beside it are admissible too (no corner is cut). Start
and goal are snapped to the nearest admissible cell centre. The shortest paths to one goal are
found once, from every cell (``RouteMap.tree_to``): a robot that strays takes its new way from
that tree without searching again.

Memory is a few bytes per cell: the graph is never stored (a search steps over the grid's 8
neighbour offsets), the distances to obstacles are kept as small integers, and a tree keeps one
byte per cell, the step towards the goal.
"""

import copy
import math

import numpy as np

# Four times the squared distance [cells^2] standing for "farther than the reach": larger than
# any within it, and with the largest offset's term added still an int32, for reaches up to
# 16,000 cells (`maps.check_route_work` allows at most 2,500).
_FAR = 1 << 30


def _quadrupled_distances_squared(occupied, window):
    """
    Return 4 x the squared distance [cells^2] from each cell's centre to the nearest obstacle.

    Obstacles at most WINDOW cells away along each axis count; ``_FAR`` where there is none.
    Exact: the distance from a centre to the square of the cell ``d`` cells away along one axis
    is ``max(|d| - 1/2, 0)``, so four times its square, ``max(2 |d| - 1, 0) ** 2``, is an
    integer; the squared distance to a cell is the sum of both axes' terms. The minimum is
    separable, taken one axis after the other; int32 arrays, updated in place, keep the pass at
    about 13 bytes per cell.

    Parameters
    ----------
    occupied : numpy.ndarray
        Shape (height, width), bool; the outside of the map counts as occupied.
    window : int
        Offsets considered along each axis, >= 0.

    Returns
    -------
    numpy.ndarray
        Shape (height, width), int32.

    """
    height, width = occupied.shape
    padded = np.pad(occupied, window, constant_values=True)
    along_rows = np.full((height + 2 * window, width), _FAR, dtype=np.int32)
    for offset in range(-window, window + 1):
        np.minimum(along_rows, max(2 * abs(offset) - 1, 0) ** 2, out=along_rows,
                   where=padded[:, window + offset:window + offset + width])
    # Freed before the second pass allocates its two arrays.
    del padded
    nearest = np.full((height, width), _FAR, dtype=np.int32)
    shifted = np.empty_like(nearest)
    for offset in range(-window, window + 1):
        np.add(along_rows[window + offset:window + offset + height],
               max(2 * abs(offset) - 1, 0) ** 2, out=shifted)
        np.minimum(nearest, shifted, out=nearest)
    return nearest


def _distances_of(quadrupled, occupied, resolution, cells):
    """Return the distances [m] (float64) of `_quadrupled_distances_squared`'s QUADRUPLED.

    0 for an OCCUPIED cell, inf from CELLS (the reach in cells) on.
    """
    nearest = quadrupled * 0.25
    distances = np.sqrt(nearest) * resolution
    distances[nearest >= cells * cells] = np.inf
    distances[occupied] = 0.0
    return distances


def _window(resolution, reach):
    """Return (REACH in cells, the offsets along an axis that can come closer than REACH)."""
    cells = reach / resolution
    return cells, int(math.floor(cells + 0.5))


def obstacle_distances(occupied, resolution, reach):
    """
    Return the distance from every cell's centre to the nearest occupied cell, up to REACH.

    Exact (see `_quadrupled_distances_squared`): the distance to the nearest occupied cell's
    square.

    Parameters
    ----------
    occupied : numpy.ndarray
        Shape (height, width), bool; the outside of the map counts as occupied.
    resolution : float
        Cell edge [m].
    reach : float
        Largest distance [m] of interest, >= 0.

    Returns
    -------
    numpy.ndarray
        Shape (height, width) [m]: 0 for an occupied cell, inf where nothing occupied is
        nearer than REACH.

    """
    occupied = np.asarray(occupied, dtype=bool)
    cells, window = _window(resolution, reach)
    return _distances_of(_quadrupled_distances_squared(occupied, window), occupied,
                         resolution, cells)


def admissible_cells(occupied, resolution, clearance):
    """
    Return the free cells whose centres keep at least CLEARANCE [m] from every occupied cell.

    Shape (height, width), bool; the outside of the map counts as occupied.
    """
    return ~np.asarray(occupied, dtype=bool) & (
        obstacle_distances(occupied, resolution, clearance) >= clearance)


# A step through cells at the clearance costs this much more than one keeping the margin.
MARGIN_COST = 1.0
# The 8 steps between neighbours (row step, column step), each beside its opposite (index ^ 1);
# a tree keeps, for every cell, the index of its step towards the goal, or one of these two.
_STEPS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (-1, -1), (1, -1), (-1, 1))
_UNREACHED = -1
_AT_GOAL = len(_STEPS)
# Rows of the grid turned into distances at a time: the float64 arrays of a block are transient.
_BLOCK_CELLS = 1 << 18


class RouteMap:
    """
    The admissible cells of a grid and the 8-connected steps between them.

    Kept per cell: the occupied, admissible and roomy cells (bool), the steps allowed from each
    (one byte, a bit per step of ``_STEPS``) and, with a margin, each cell's share of a step's
    extra cost (float32): some 8 bytes a cell, on a grid padded by one cell.

    Parameters
    ----------
    occupied : numpy.ndarray
        Shape (height, width), bool: ``occupied[row, column]``, row 0 at the smallest y.
    resolution : float
        Cell edge [m].
    origin : array_like
        Shape (2,): world position of cell (0, 0)'s lower-left corner [m].
    clearance : float
        Distance [m] a path's cell centres keep from every occupied cell, >= 0.
    margin : float
        Further distance [m] a path keeps where there is room: a step between cells closer
        than clearance + margin costs up to ``1 + MARGIN_COST`` times its length, and a path
        is pulled taut only along cells that keep it (or its own cells). Shortest paths hug
        obstacles at the clearance, where robots meeting there have no room to pass.

    """

    def __init__(self, occupied, resolution, origin, clearance, margin=0.0):
        self.resolution = float(resolution)
        self.origin = np.asarray(origin, dtype=float)
        self.occupied = np.asarray(occupied, dtype=bool)
        height, width = self.occupied.shape
        cells, window = _window(self.resolution, clearance + margin)
        quadrupled = _quadrupled_distances_squared(self.occupied, window)
        self.admissible = np.empty((height, width), dtype=bool)
        # Cells that keep the margin too.
        self.roomy = np.empty((height, width), dtype=bool)
        # Half the extra cost a step pays per cell at either end, on the padded grid.
        self._extra = (np.zeros((height + 2, width + 2), dtype=np.float32) if margin > 0.0
                       else None)
        rows = max(1, _BLOCK_CELLS // width)
        for first in range(0, height, rows):
            block = slice(first, first + rows)
            distances = _distances_of(quadrupled[block], self.occupied[block], self.resolution,
                                      cells)
            self.admissible[block] = ~self.occupied[block] & (distances >= clearance)
            self.roomy[block] = self.admissible[block] & (distances >= clearance + margin)
            if margin > 0.0:
                self._extra[1:-1, 1:-1][block] = 0.5 * MARGIN_COST * np.clip(
                    (clearance + margin - distances) / margin, 0.0, 1.0)
        del quadrupled
        self._width = width
        self._padded_width = width + 2
        self._link()
        self._offsets = np.array([step_row * self._padded_width + step_column
                                  for step_row, step_column in _STEPS])
        self._lengths = self.resolution * np.hypot(*np.array(_STEPS, dtype=float).T)

    def _link(self):
        """Find the steps allowed between the admissible cells (``_allowed``)."""
        height, width = self.admissible.shape
        self._any_admissible = bool(self.admissible.any())
        ok = np.pad(self.admissible, 1, constant_values=False)
        # Bit k: the step _STEPS[k] from this padded cell is allowed.
        self._allowed = np.zeros(ok.shape, dtype=np.uint8)
        inner = self._allowed[1:-1, 1:-1]
        for bit, (step_row, step_column) in enumerate(_STEPS):
            linked = self.admissible & ok[1 + step_row:1 + step_row + height,
                                          1 + step_column:1 + step_column + width]
            if step_row and step_column:
                # Both cells beside a diagonal step must be admissible.
                linked &= ok[1 + step_row:1 + step_row + height, 1:1 + width]
                linked &= ok[1:1 + height, 1 + step_column:1 + step_column + width]
            inner |= linked.view(np.uint8) << bit

    def without(self, cells):
        """Return a copy of this map on which CELLS (K, 2) int, (row, column), are not admissible.

        Its paths go round those cells (a passage a robot will not take); the occupied cells,
        and with them `blocked`, are this map's. The grids not changed are shared.
        """
        other = copy.copy(self)
        closed = np.zeros(self.admissible.shape, dtype=bool)
        closed[tuple(np.asarray(cells, dtype=int).reshape(-1, 2).T)] = True
        other.admissible = self.admissible & ~closed
        other.roomy = self.roomy & ~closed
        other._link()
        return other

    def centres(self, cells):
        """Return the world positions (K, 2) [m] of the centres of flat cell indices CELLS (K,)."""
        cells = np.asarray(cells)
        rows, columns = np.divmod(cells, self._width)
        return self.origin + self.resolution * (np.stack([columns, rows], axis=-1) + 0.5)

    def cell_of(self, position):
        """Return the (row, column) of the cell holding POSITION (2,), None if off the map."""
        column, row = np.floor((np.asarray(position, dtype=float) - self.origin)
                               / self.resolution)
        height, width = self.occupied.shape
        if not (0 <= row < height and 0 <= column < width):
            return None
        return int(row), int(column)

    def blocked(self, position):
        """Whether POSITION (2,) lies in an occupied cell or off the map."""
        cell = self.cell_of(position)
        return cell is None or bool(self.occupied[cell])

    def in_sight(self, start, end, cells=None):
        """Whether the straight way from START to END (2,) [m] runs through admissible cells.

        CELLS (height, width) bool, if given, are the cells allowed instead.

        Every cell whose inside the way crosses counts (found between the way's crossings of
        the grid lines); one it only touches at a corner does not, nor the cell of START: a
        robot pushed closer to an obstacle than its clearance may still head back along its
        way.
        """
        first = (np.asarray(start, dtype=float) - self.origin) / self.resolution
        last = (np.asarray(end, dtype=float) - self.origin) / self.resolution
        step = last - first
        crossings = [np.array([0.0, 1.0])]
        for axis in range(2):
            if step[axis] != 0.0:
                low, high = sorted((first[axis], last[axis]))
                lines = np.arange(math.floor(low) + 1.0, math.ceil(high))
                crossings.append((lines - first[axis]) / step[axis])
        fractions = np.unique(np.concatenate(crossings))
        middles = 0.5 * (fractions[:-1] + fractions[1:])
        columns, rows = np.floor(first + middles[:, None] * step).astype(int).T
        allowed = self.admissible if cells is None else cells
        height, width = allowed.shape
        inside = (rows >= 0) & (rows < height) & (columns >= 0) & (columns < width)
        if not inside.all():
            return False
        own = (rows == math.floor(first[1])) & (columns == math.floor(first[0]))
        return bool(allowed[rows[~own], columns[~own]].all())

    def snapped(self, position):
        """Return the flat index of the admissible cell whose centre is nearest POSITION (2,).

        None when no cell is admissible; ties go to the lowest index. Searched in growing
        windows of cells around POSITION first: a cell farther than k cells along an axis from
        POSITION's cell has its centre more than k + 1/2 cells away.
        """
        if not self._any_admissible:
            return None
        position = np.asarray(position, dtype=float)
        cell = self.cell_of(position)
        if cell is not None:
            height, width = self.admissible.shape
            row, column = cell
            reach = 1
            while reach < max(height, width):
                rows = slice(max(row - reach, 0), min(row + reach + 1, height))
                columns = slice(max(column - reach, 0), min(column + reach + 1, width))
                found_rows, found_columns = np.nonzero(self.admissible[rows, columns])
                if len(found_rows):
                    # Row-major order within the window is the flat order of the map.
                    found = (found_rows + rows.start) * width + found_columns + columns.start
                    offsets = self.centres(found) - position
                    distances = np.einsum('ij,ij->i', offsets, offsets)
                    best = int(np.argmin(distances))
                    if distances[best] < ((reach + 0.5) * self.resolution) ** 2:
                        return int(found[best])
                reach *= 4
        # Off the map: every admissible cell, a block of rows at a time, in flat order.
        best, nearest = None, np.inf
        height, width = self.admissible.shape
        rows = max(1, _BLOCK_CELLS // width)
        for first in range(0, height, rows):
            found = np.flatnonzero(self.admissible[first:first + rows]) + first * width
            if len(found):
                offsets = self.centres(found) - position
                distances = np.einsum('ij,ij->i', offsets, offsets)
                index = int(np.argmin(distances))
                if distances[index] < nearest:
                    best, nearest = int(found[index]), distances[index]
        return best

    def tree_to(self, goal):
        """Return the `RouteTree` of the shortest paths from every cell to GOAL (2,) [m].

        A goal in an obstacle or off the map has no way to it.
        """
        cell = None if self.blocked(goal) else self.snapped(goal)
        goal = np.asarray(goal, dtype=float)
        if cell is None:
            return RouteTree(self, goal, None, None)
        return RouteTree(self, goal, cell, self._search(self._padded(cell)))

    def _padded(self, cell):
        """Return the index on the padded grid of the flat cell index CELL."""
        row, column = divmod(int(cell), self._width)
        return (row + 1) * self._padded_width + column + 1

    def _search(self, goal):
        """
        Return the step towards GOAL (a padded index) of every padded cell, int8.

        Dijkstra's search from GOAL over the allowed steps, a band of cells per round of array
        work: a step costs at least a cell edge, so no cell less than one edge farther than the
        nearest unsettled one can be improved through another unsettled one; the round settles
        them all. (A cell improved after all, by a rounding, is searched from again.) A cell's
        step is the one of its latest improvement, to a cell strictly nearer the goal, so the
        steps form a tree. Transient: the float64 distances and a flag, 9 bytes per cell.
        """
        size = self._allowed.size
        steps = np.full(size, _UNREACHED, dtype=np.int8)
        distances = np.full(size, np.inf)
        queued = np.zeros(size, dtype=bool)
        allowed = self._allowed.ravel()
        extra = None if self._extra is None else self._extra.ravel()
        steps[goal], distances[goal], queued[goal] = _AT_GOAL, 0.0, True
        frontier = np.array([goal])
        while len(frontier):
            reached = distances[frontier]
            settled = reached < reached.min() + self.resolution
            cells, frontier = frontier[settled], frontier[~settled]
            queued[cells] = False
            reached, bits = reached[settled], allowed[cells]
            own_extra = None if extra is None else extra[cells].astype(float)
            found = [frontier]
            for step, (offset, length) in enumerate(zip(self._offsets, self._lengths,
                                                        strict=True)):
                going = (bits & (1 << step)) != 0
                targets = cells[going] + offset
                if extra is None:
                    through = reached[going] + length
                else:
                    through = reached[going] + length * (1.0 + own_extra[going]
                                                         + extra[targets])
                better = through < distances[targets]
                targets = targets[better]
                distances[targets] = through[better]
                # A step from the target back to this cell: the opposite of STEP.
                steps[targets] = step ^ 1
                targets = targets[~queued[targets]]
                queued[targets] = True
                found.append(targets)
            frontier = np.concatenate(found)
        return steps


class RouteTree:
    """The shortest paths from every cell of a `RouteMap` to one goal (`RouteMap.tree_to`).

    Kept: a byte per cell of the padded grid, the step towards the goal.
    """

    def __init__(self, route_map, goal, goal_cell, steps):
        self.route_map = route_map
        self.goal = goal
        self.goal_cell = goal_cell
        self._steps = steps

    def cells_from(self, position):
        """Return the flat indices (K,) of the grid path's cells from POSITION (2,) to the goal.

        From the admissible cell nearest POSITION to the goal's; None if no path reaches it.
        """
        route_map = self.route_map
        start = route_map.snapped(position)
        if start is None or self.goal_cell is None:
            return None
        cell = route_map._padded(start)
        if self._steps[cell] == _UNREACHED:
            return None
        padded = [cell]
        while self._steps[cell] != _AT_GOAL:
            cell += int(route_map._offsets[self._steps[cell]])
            padded.append(cell)
        rows, columns = np.divmod(np.array(padded), route_map._padded_width)
        return (rows - 1) * route_map._width + columns - 1

    def route_from(self, position, taut=True):
        """
        Return the shortest path from POSITION to the goal, or None if no path reaches it.

        Parameters
        ----------
        position : array_like
            Shape (2,) [m].
        taut : bool
            Pull the grid path taut: from each waypoint on, the next is the farthest centre of
            the path still in sight along cells that keep the margin or are the path's own
            (``RouteMap.in_sight``), found by
            doubling and halving the step. A path along the 8 grid directions strays from the
            straight way up to 0.4 times its length; robots whose ways kink that way cross
            each other where straight ways would not. False: the grid path itself.

        Returns
        -------
        numpy.ndarray or None
            Shape (K, 2) [m]: from the centre of the snapped start cell over the centres where
            the path turns to the centre of the snapped goal cell, then the goal itself if it is
            not that centre.

        """
        route_map = self.route_map
        cells = self.cells_from(position)
        if cells is None:
            return None
        points = route_map.centres(cells)
        if taut:
            allowed = route_map.roomy.copy()
            allowed.ravel()[cells] = True
            points = points[_taut(points, lambda a, b: route_map.in_sight(a, b, allowed))]
        elif len(points) > 2:
            steps = np.diff(points, axis=0)
            # A waypoint where the direction stays the same is not needed.
            turns = np.abs(steps[1:, 0] * steps[:-1, 1] - steps[1:, 1] * steps[:-1, 0]) > (
                1e-9 * route_map.resolution ** 2)
            points = np.concatenate([points[:1], points[1:-1][turns], points[-1:]])
        if not np.array_equal(points[-1], self.goal):
            points = np.concatenate([points, self.goal[None]])
        return points


def _taut(points, in_sight):
    """Return the indices of the waypoints of POINTS (K, 2) pulled taut (see route_from)."""
    last = len(points) - 1
    kept = [0]
    while kept[-1] < last:
        here = kept[-1]
        seen, step = here + 1, 1
        while seen + step <= last and in_sight(points[here], points[seen + step]):
            seen += step
            step *= 2
        hidden = min(seen + step, last + 1)
        while hidden - seen > 1:
            middle = (seen + hidden) // 2
            if in_sight(points[here], points[middle]):
                seen = middle
            else:
                hidden = middle
        kept.append(seen)
    return np.array(kept)


def path_length(path):
    """Return the length [m] of the polyline PATH (K, 2)."""
    return float(np.linalg.norm(np.diff(np.asarray(path, dtype=float), axis=0), axis=1).sum())
