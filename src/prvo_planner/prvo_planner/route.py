"""
The way to a goal on an occupancy grid: the shortest path through cells a robot fits in, no ROS.

A cell is admissible when its centre keeps at least a clearance (the robot's radius) from every
occupied cell, the map's outside counting as occupied. Paths run between admissible cells'
centres on the 8-connected grid: a straight step costs one cell edge, a diagonal step
sqrt(2) of it and only where both cells beside it are admissible too (no corner is cut). Start
and goal are snapped to the nearest admissible cell centre. The shortest paths to one goal are
found once, from every cell (``RouteMap.tree_to``): a robot that strays takes its new way from
that tree without searching again.
"""

import math

import numpy as np


def _edge_distances_squared(offsets):
    """Return the squared distances (in cells) from a cell centre to cells OFFSETS away.

    The distance from a centre to the square of the cell ``d`` cells away along one axis is
    ``max(|d| - 1/2, 0)``; the squared distance to a cell is the sum of both axes' squares.
    """
    return np.maximum(np.abs(offsets) - 0.5, 0.0) ** 2


def obstacle_distances(occupied, resolution, reach):
    """
    Return the distance from every cell's centre to the nearest occupied cell, up to REACH.

    Exact: the squared distance from a centre to the nearest occupied cell's square is the
    smallest sum of the per-axis terms of ``_edge_distances_squared`` over occupied cells, a
    separable minimum taken one axis after the other over the offsets that can come closer
    than REACH.

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
    height, width = occupied.shape
    cells = reach / resolution
    # Cells farther than this many cells along an axis are at least REACH away.
    window = int(math.floor(cells + 0.5))
    padded = np.pad(occupied, window, constant_values=True)
    along_rows = np.full((height + 2 * window, width), np.inf)
    for offset in range(-window, window + 1):
        cost = float(_edge_distances_squared(offset))
        along_rows = np.minimum(along_rows, np.where(
            padded[:, window + offset:window + offset + width], cost, np.inf))
    nearest = np.full((height, width), np.inf)
    for offset in range(-window, window + 1):
        cost = float(_edge_distances_squared(offset))
        nearest = np.minimum(nearest, along_rows[window + offset:window + offset + height] + cost)
    distances = np.sqrt(nearest) * resolution
    distances[nearest >= cells * cells] = np.inf
    distances[occupied] = 0.0
    return distances


def admissible_cells(occupied, resolution, clearance):
    """
    Return the free cells whose centres keep at least CLEARANCE [m] from every occupied cell.

    Shape (height, width), bool; the outside of the map counts as occupied.
    """
    return ~np.asarray(occupied, dtype=bool) & (
        obstacle_distances(occupied, resolution, clearance) >= clearance)


# A step through cells at the clearance costs this much more than one keeping the margin.
MARGIN_COST = 1.0


class RouteMap:
    """
    The admissible cells of a grid and the 8-connected graph between them.

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
        distances = obstacle_distances(occupied, self.resolution, clearance + margin)
        self.admissible = ~self.occupied & (distances >= clearance)
        # Cells that keep the margin too.
        self.roomy = self.admissible & (distances >= clearance + margin)
        closeness = (np.clip((clearance + margin - distances) / margin, 0.0, 1.0) if margin > 0.0
                     else np.zeros(distances.shape))
        closeness = closeness.ravel()
        height, width = self.admissible.shape
        self._width = width
        rows, columns = np.nonzero(self.admissible)
        # The admissible cells in flat order, for snapping.
        self._admissible_index = rows * width + columns
        ok = np.pad(self.admissible, 1, constant_values=False)
        sources, targets, weights = [], [], []
        index = np.arange(height * width).reshape(height, width)
        straight, diagonal = self.resolution, self.resolution * math.sqrt(2.0)
        # (row step, column step): right, up, up-right, up-left; the graph is undirected.
        for step_row, step_column, weight in ((0, 1, straight), (1, 0, straight),
                                              (1, 1, diagonal), (1, -1, diagonal)):
            there = ok[1 + step_row:1 + step_row + height, 1 + step_column:1 + step_column + width]
            linked = self.admissible & there
            if step_row and step_column:
                # Both cells beside a diagonal step must be admissible.
                linked &= ok[1 + step_row:1 + step_row + height, 1:1 + width]
                linked &= ok[1:1 + height, 1 + step_column:1 + step_column + width]
            here = index[linked]
            there_index = here + step_row * width + step_column
            sources.append(here)
            targets.append(there_index)
            weights.append(weight * (1.0 + MARGIN_COST * 0.5 * (
                closeness[here] + closeness[there_index])))
        size = height * width
        sources, targets = np.concatenate(sources), np.concatenate(targets)
        weights = np.concatenate(weights)
        # Both directions stored once: an undirected search would symmetrise on every call.
        # scipy.sparse is imported here, not with the module: it costs a process 0.2-0.3 s of
        # CPU, and most planners (those without a map) never build a route.
        from scipy.sparse import coo_matrix
        self._graph = coo_matrix(
            (np.concatenate([weights, weights]),
             (np.concatenate([sources, targets]), np.concatenate([targets, sources]))),
            shape=(size, size)).tocsr()

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
        if len(self._admissible_index) == 0:
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
        offsets = self.centres(self._admissible_index) - position
        return int(self._admissible_index[np.argmin(np.einsum('ij,ij->i', offsets, offsets))])

    def tree_to(self, goal):
        """Return the `RouteTree` of the shortest paths from every cell to GOAL (2,) [m].

        A goal in an obstacle or off the map has no way to it.
        """
        cell = None if self.blocked(goal) else self.snapped(goal)
        if cell is None:
            return RouteTree(self, np.asarray(goal, dtype=float), None, None, None)
        from scipy.sparse.csgraph import dijkstra
        distances, predecessors = dijkstra(self._graph, directed=True, indices=cell,
                                           return_predecessors=True)
        return RouteTree(self, np.asarray(goal, dtype=float), cell, distances, predecessors)


class RouteTree:
    """The shortest paths from every cell of a `RouteMap` to one goal (`RouteMap.tree_to`)."""

    def __init__(self, route_map, goal, goal_cell, distances, predecessors):
        self.route_map = route_map
        self.goal = goal
        self.goal_cell = goal_cell
        self._distances = distances
        self._predecessors = predecessors

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
        start = route_map.snapped(position)
        if start is None or self.goal_cell is None or not np.isfinite(self._distances[start]):
            return None
        cells = [start]
        while cells[-1] != self.goal_cell:
            cells.append(int(self._predecessors[cells[-1]]))
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
