"""
One-way passages of a map: where two robots cannot pass each other, and where to wait, no ROS.

Issue 39: robots that meet in a door freeze unless someone goes first, and whoever waits needs
a spot that leaves the way out free. This module finds both from the occupancy grid alone, so
every planner reading the same map finds the same passages. (`passages` is another matter: the
clear width ahead of one stalled robot, measured on its obstacles, for a report.)

**The rule.** A robot of radius r that keeps a margin m needs a lane 2 r + m wide; two robots
pass each other where the free space is at least ``passing_width = 2 (2 r + m)`` wide. The
width is read on the ridge of the free space, the cells midway between two obstacles a robot
could pass between (where the nearest occupied cell jumps by at least 2 r from a cell to its
neighbour): a ridge cell r to half the passing width from the nearest occupied cell is
*narrow*, one farther is *open*. A connected stretch of narrow ridge is a passage when it meets
open cells in two or more separate places, its *ends*: routes pass through it from one open
space to another. A stretch that meets them in one place only (a room's corner, a dead-end
alcove) is no passage: nothing passes through it. A door narrower than 2 r is none either: no
robot fits. A passage's cells are the centres of robots within it: within a free disc about its
ridge (of the nearest ridge cell's clearance) less r. Before a door in a thin wall the ridge is
narrow for about half the passing width on either side: there the jambs are nearer than half
the passing width, and robots meeting there hinder each other.

The margin is the trade-off: a larger one finds more passages (robots take turns in corridors
they could share, and the traffic through them slows); a smaller one lets robots meet where
noise and the certified clearances leave no room, the freeze of issue 39.

**Waiting spots.** Each end has the free cell centre nearest its entrance that keeps r + m from
every occupied cell and 2 r + m from every passage's cells (a robot waiting there leaves the
margin to any robot inside) and from the spots chosen before it (passages in the order of
their cells, row by row); that lies ahead of the entrance (on the open side), at least 2 r + m
off the line out of the passage at that end (a robot coming out along it passes with its
margin), and can be reached from the end without entering a passage; searched within
``WAIT_REACH`` passing widths of the entrance, None where no cell qualifies.

Widths come from a Euclidean distance transform of the grid (scipy.ndimage), from cell centres
to occupied cells' edges; they are exact to within a cell (never more than the grid leaves).
The map's outside counts as occupied, as it does for the route (`route.RouteMap`).
"""

from dataclasses import dataclass
import math

import numpy as np

from prvo_planner.maps import MAX_PADDED_CELLS, MapTooLargeError, occupied_cells

# Waiting spots are searched for within this many passing widths of an entrance.
WAIT_REACH = 2.0
# Bounds on the work of `find_passages`, in the style of `maps.check_route_work`. The distance
# transforms and labellings visit every cell a few times and hold about 22 bytes a cell at
# their peak (a 2000 x 2000 map of open space: 0.5 s of one core, 90 MB), on at most
# ``MAX_CELLS``, as many as a route may pad (`maps.MAX_PADDED_CELLS`). Each stretch of narrow
# ridge is then examined within its bounding box, one cell wider on every side, each passage's
# cells within half a passing width of that box, and each end's waiting spot searched for
# within a square window: their areas summed are at most ``MAX_LOCAL_CELLS``, at about 250 ns a
# cell some 10 s (a 2000 x 2000 office of 304 doors asks for 1.4e7 cells, 3 s in all).
MAX_CELLS = MAX_PADDED_CELLS
MAX_LOCAL_CELLS = 40_000_000
# Cells per block of `_clearances_and_ridge`'s arithmetic: bounds its temporary arrays.
_BLOCK_CELLS = 1 << 16
# 8-connectivity for labelling and dilation: a diagonal step keeps a region connected.
_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class PassageEnd:
    """
    Where a passage opens onto open space.

    Attributes
    ----------
    entrance : numpy.ndarray
        Shape (2,): the middle of the passage's cells that touch this open space [m].
    outward : numpy.ndarray
        Shape (2,): unit vector from the entrance into the open space.
    waiting_spot : numpy.ndarray or None
        Shape (2,): where a robot waits to enter [m] (see the module's rule), None where no
        cell near the entrance qualifies.

    """

    entrance: np.ndarray
    outward: np.ndarray
    waiting_spot: np.ndarray | None


@dataclass(frozen=True)
class Passage:
    """
    A stretch of free space too narrow for two robots to pass each other, open at its ends.

    Attributes
    ----------
    ends : tuple of PassageEnd
        Two or more (more where narrow corridors meet), ordered by their entrances' (x, y).
    width : float
        Clear width [m] of the passage where it is narrowest on the way between its ends:
        twice the largest clearance a path joining every end keeps from occupied cells.
    centre_lines : tuple of numpy.ndarray
        One per end after the first, shape (K, 2) each [m]: the shortest way from the first
        end's entrance to that end's through the cells that keep half the width, from cell
        centre to cell centre.
    length : float
        Length [m] of the longest centre line.
    axis : numpy.ndarray
        Shape (2,): unit vector from the first end's entrance to the second's.
    cells : numpy.ndarray
        Shape (C, 2), int: the (row, column) of every cell of the passage in the grid.

    """

    ends: tuple
    width: float
    centre_lines: tuple
    length: float
    axis: np.ndarray
    cells: np.ndarray


def passing_width(radius, margin):
    """Return the free width [m] two robots of RADIUS [m] need to pass keeping MARGIN [m]."""
    return 2.0 * (2.0 * radius + margin)


def find_passages(grid, radius, margin, unknown_is_occupied=True):
    """
    Return the passages of a grid too narrow for two robots to pass, with waiting spots.

    Parameters
    ----------
    grid : maps.GridMap
        The map; cells are occupied as `maps.occupied_cells` says, the outside is occupied.
    radius : float
        The robots' radius [m], positive (the planning radius, to keep what the planner
        keeps).
    margin : float
        The margin [m] >= 0 each robot keeps beside its lane (see the module's rule).
    unknown_is_occupied : bool
        Whether unknown cells are obstacles.

    Returns
    -------
    tuple of Passage
        Ordered by their first end's entrance (x, y).

    Raises
    ------
    ValueError
        RADIUS or MARGIN out of range.
    maps.MapTooLargeError
        A map whose passages would take more work than ``MAX_CELLS`` and ``MAX_LOCAL_CELLS``
        allow.

    """
    radius, margin = float(radius), float(margin)
    if not (math.isfinite(radius) and radius > 0.0):
        raise ValueError(f'radius must be a positive number of metres, got {radius!r}')
    if not (math.isfinite(margin) and margin >= 0.0):
        raise ValueError(f'margin must be a non-negative number of metres, got {margin!r}')
    height, width = grid.shape
    if height * width > MAX_CELLS:
        raise MapTooLargeError(f'{width} x {height} cells: finding passages visits at most '
                               f'{MAX_CELLS:.3g} cells')
    # scipy.ndimage is imported here, not with the module: it costs a process a fraction of a
    # second of CPU, and most planners never read a map.
    from scipy import ndimage
    resolution = grid.resolution
    clearance, ridge = _clearances_and_ridge(occupied_cells(grid, unknown_is_occupied),
                                             resolution, radius)
    fits = clearance >= radius
    half = 0.5 * passing_width(radius, margin)
    open_space = clearance >= half
    # The ridge where it is narrow, one cell thicker so that a gap of a cell does not split it.
    narrow = ndimage.binary_dilation(ridge & fits & ~open_space, structure=_EIGHT)
    narrow &= fits & ~open_space
    labels, _ = ndimage.label(narrow, structure=_EIGHT)
    boxes = [_grown(box, 1, labels.shape) for box in ndimage.find_objects(labels)]
    window = int(math.ceil(WAIT_REACH * 2.0 * half / resolution))
    local = sum(_area(box) for box in boxes)
    if local > MAX_LOCAL_CELLS:
        raise MapTooLargeError(f'{width} x {height} cells: its narrow places span {local:.3g} '
                               f'cells (at most {MAX_LOCAL_CELLS:.3g})')
    # A passage's cells lie within half the passing width less r of its ridge.
    spread = int(math.ceil((half - radius) / resolution)) + 1
    through = []
    for label, box in enumerate(boxes, start=1):
        mask = labels[box] == label
        _, count = ndimage.label(_rim(mask, open_space[box]), structure=_EIGHT)
        if count >= 2:
            through.append((label, box, _grown(box, spread, labels.shape)))
            local += count * (2 * window + 1) ** 2 + _area(through[-1][2])
    if local > MAX_LOCAL_CELLS:
        raise MapTooLargeError(f'{width} x {height} cells: its passages and waiting spots span '
                               f'{local:.3g} cells (at most {MAX_LOCAL_CELLS:.3g})')
    # Where a robot's centre is in a passage: its body within a disc of free space centred on
    # the passage's ridge (nearly: the disc of the nearest ridge cell).
    in_passages = np.zeros_like(fits)
    cells = []
    for label, _, near in through:
        distances, (rows, columns) = ndimage.distance_transform_edt(labels[near] != label,
                                                                    return_indices=True)
        inside = fits[near] & (distances * resolution
                               <= clearance[near][rows, columns] - radius)
        in_passages[near] |= inside
        cells.append(_cells_in(inside, near))
    # Spots already chosen, which later ones keep clear of: two waiting robots do not overlap.
    taken = []
    passages = [_passage(grid, clearance, fits, open_space, in_passages, labels[box] == label,
                         box, passage_cells, radius, margin, window, taken)
                for (label, box, _), passage_cells in zip(through, cells, strict=True)]
    return tuple(sorted(passages, key=lambda passage: tuple(passage.ends[0].entrance)))


def _clearances_and_ridge(occupied, resolution, radius):
    """
    Return each cell centre's distance [m] from the nearest occupied cell's edge, and the ridge.

    OCCUPIED (height, width) bool; the map's outside counts as occupied. The distance is the
    one between cell centres less half a cell: exact along the grid's axes, within a cell
    elsewhere; negative for occupied cells. The ridge (height, width) bool holds the free cells
    where the nearest occupied cell jumps between obstacles a robot of RADIUS [m] could pass
    between: it is at least 2 RADIUS (and two cells) from the nearest occupied cell of one of
    the cell's four neighbours. The middle of a door, of a corridor, of a room; a straight or
    staircase wall alone makes none (its nearest cells move by a cell or two at most), a
    concave corner one along its bisector, from where the walls are 2 RADIUS apart.

    Only the nearest cells are asked of the transform (8 bytes a cell) and the distances and
    jumps are taken from them a block of rows at a time: scipy's distances would cost 40 bytes
    a cell more at their peak.
    """
    from scipy import ndimage
    height, width = occupied.shape
    nearest = ndimage.distance_transform_edt(np.pad(~occupied, 1), return_distances=False,
                                             return_indices=True)
    jump = max(2.0 * radius / resolution, 2.0) ** 2
    clearance = np.empty((height, width))
    ridge = np.zeros((height, width), dtype=bool)
    block = max(1, _BLOCK_CELLS // (width + 2))
    for first in range(0, height, block):
        last = min(first + block, height)
        # Padded rows first + 1 .. last, and the rows beside them; int64: no square overflows.
        here = nearest[:, first + 1:last + 1, 1:-1].astype(np.int64)
        cell = np.mgrid[first + 1:last + 1, 1:width + 1]
        clearance[first:last] = (np.sqrt(np.sum((here - cell) ** 2, axis=0)) - 0.5) * resolution
        for step_row, step_column in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            beside = nearest[:, first + 1 + step_row:last + 1 + step_row,
                             1 + step_column:width + 1 + step_column]
            ridge[first:last] |= np.sum((here - beside) ** 2, axis=0) >= jump
    ridge &= ~occupied
    return clearance, ridge


def _rim(mask, open_space):
    """Return the OPEN_SPACE cells (h, w) bool that touch MASK (h, w) bool, 8-connected."""
    from scipy import ndimage
    return ndimage.binary_dilation(mask, structure=_EIGHT) & open_space & ~mask


def _grown(box, cells, shape):
    """Return the slices BOX grown by CELLS on every side, clipped to SHAPE."""
    return tuple(slice(max(part.start - cells, 0), min(part.stop + cells, size))
                 for part, size in zip(box, shape, strict=True))


def _area(box):
    """Return the number of cells in the slices BOX."""
    return math.prod(part.stop - part.start for part in box)


def _world(grid, rows, columns):
    """Return the world centres (K, 2) [m] of the cells ROWS, COLUMNS (K,)."""
    return grid.origin + grid.resolution * (np.stack([columns, rows], axis=-1) + 0.5)


def _passage(grid, clearance, fits, open_space, in_passages, mask, box, cells, radius, margin,
             window, taken):
    """
    Return the Passage whose ridge is MASK in the slices BOX and whose cells are CELLS.

    CELLS (rows, columns); each piece of OPEN_SPACE (height, width) bool touching MASK makes an
    end; IN_PASSAGES (height, width) bool holds every passage's cells. Its waiting spots keep
    clear of those TAKEN (a list of (2,) [m]) and are added to it.
    """
    from scipy import ndimage
    sides, count = ndimage.label(_rim(mask, open_space[box]), structure=_EIGHT)
    mouths, entrances, beyond = [], [], []
    for side in range(1, count + 1):
        outside = sides == side
        mouth = mask & ndimage.binary_dilation(outside, structure=_EIGHT)
        mouths.append(mouth)
        entrances.append(_world(grid, *_cells_in(mouth, box)).mean(axis=0))
        beyond.append(_world(grid, *_cells_in(outside, box)).mean(axis=0))
    order = sorted(range(count), key=lambda index: tuple(entrances[index]))
    mouths = [mouths[index] for index in order]
    entrances = [entrances[index] for index in order]
    ridge_clearance = np.where(mask, clearance[box], -np.inf)
    bottleneck = _bottleneck(ridge_clearance, mouths)
    lines = _centre_lines(grid, box, ridge_clearance >= bottleneck, mouths, entrances)
    # Each end's way out continues its centre line; the way to the open cells beside its
    # mouth where the line is a single cell.
    tails = [lines[0][::-1]] + lines
    reach = passing_width(radius, margin)
    outwards = [_unit(_tail(tail, reach), beyond[index] - entrance)
                for tail, index, entrance in zip(tails, order, entrances, strict=True)]
    ends = []
    for entrance, outward in zip(entrances, outwards, strict=True):
        spot = _waiting_spot(grid, clearance, fits, in_passages, entrance, outward, radius,
                             margin, window, taken)
        ends.append(PassageEnd(entrance, outward, spot))
        if spot is not None:
            taken.append(spot)
    return Passage(
        ends=tuple(ends),
        width=2.0 * float(bottleneck), centre_lines=tuple(lines),
        length=max(float(np.sum(np.linalg.norm(np.diff(line, axis=0), axis=1)))
                   for line in lines),
        axis=_unit(entrances[1] - entrances[0], outwards[1]),
        cells=np.stack(cells, axis=1))


def _cells_in(mask, box):
    """Return the (rows, columns) in the grid of MASK's cells, MASK in the slices BOX."""
    rows, columns = np.nonzero(mask)
    return rows + box[0].start, columns + box[1].start


def _tail(line, reach):
    """Return the step from LINE's (K, 2) [m] point REACH [m] before its end to its end."""
    back = np.cumsum(np.linalg.norm(np.diff(line[::-1], axis=0), axis=1))
    return line[-1] - line[::-1][min(int(np.searchsorted(back, reach)) + 1, len(line) - 1)]


def _unit(vector, otherwise):
    """Return VECTOR (2,) made a unit vector, or OTHERWISE's unit vector where it is zero."""
    norm = np.linalg.norm(vector)
    return vector / norm if norm > 0.0 else otherwise / np.linalg.norm(otherwise)


def _bottleneck(clearance, mouths):
    """
    Return the largest clearance [m] a path of cells joining every mouth keeps throughout.

    CLEARANCE (h, w) [m], -inf outside the passage; MOUTHS, (h, w) bool each. Bisection over
    the clearances that occur: a threshold joins the mouths when one 8-connected set of cells
    at or above it meets all of them.
    """
    from scipy import ndimage
    levels = np.unique(clearance[np.isfinite(clearance)])
    low, high = 0, len(levels) - 1
    while low < high:
        middle = (low + high + 1) // 2
        labels, _ = ndimage.label(clearance >= levels[middle], structure=_EIGHT)
        shared = set(np.unique(labels[mouths[0]]))
        for mouth in mouths[1:]:
            shared &= set(np.unique(labels[mouth]))
        if shared - {0}:
            low = middle
        else:
            high = middle - 1
    return levels[low]


def _centre_lines(grid, box, keeps, mouths, entrances):
    """
    Return the shortest ways (K, 2) [m] from the first mouth to each other one through KEEPS.

    KEEPS and MOUTHS (h, w) bool, in the grid's slices BOX. Each way runs, in 8-connected
    steps of one or sqrt(2) cells, between the cells of KEEPS in its two mouths nearest their
    ENTRANCES (2,) [m] (the first of equals in row-major order). A mouth that KEEPS does not
    reach is joined by the straight line between the two cells.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    height, width = keeps.shape
    index = np.arange(height * width).reshape(height, width)
    padded = np.pad(keeps, 1, constant_values=False)
    sources, targets, weights = [], [], []
    for step_row, step_column in ((0, 1), (1, 0), (1, 1), (1, -1)):
        linked = keeps & padded[1 + step_row:1 + step_row + height,
                                1 + step_column:1 + step_column + width]
        here = index[linked]
        sources.append(here)
        targets.append(here + step_row * width + step_column)
        weights.append(np.full(len(here), math.hypot(step_row, step_column)))
    sources, targets = np.concatenate(sources), np.concatenate(targets)
    weights = np.concatenate(weights) * grid.resolution
    graph = coo_matrix((np.concatenate([weights, weights]),
                        (np.concatenate([sources, targets]), np.concatenate([targets, sources]))),
                       shape=(height * width,) * 2).tocsr()
    centres = _world(grid, *_cells_in(np.ones_like(keeps), box)).reshape(height, width, 2)
    starts = [int(np.argmin(np.where(mouth & keeps, np.linalg.norm(centres - entrance, axis=-1),
                                     np.inf)))
              for mouth, entrance in zip(mouths, entrances, strict=True)]
    _, predecessors = dijkstra(graph, indices=starts[0], return_predecessors=True)
    lines = []
    for goal in starts[1:]:
        if goal != starts[0] and predecessors[goal] < 0:
            lines.append(centres.reshape(-1, 2)[[starts[0], goal]])
            continue
        path = [goal]
        while path[-1] != starts[0]:
            path.append(int(predecessors[path[-1]]))
        lines.append(centres.reshape(-1, 2)[path[::-1]])
    return lines


def _waiting_spot(grid, clearance, fits, in_passages, entrance, outward, radius, margin,
                  window, taken):
    """
    Return the waiting spot (2,) [m] of the end at ENTRANCE facing OUTWARD, or None.

    The module's rule, searched in the square of WINDOW cells on every side of the entrance's
    cell: through cells the robot FITS in outside IN_PASSAGES (height, width) bool, reached
    from those that touch a passage ahead of the entrance (on OUTWARD's side), 2 r + m from
    every spot TAKEN (a list of (2,) [m]). Ties go to the spot on the right of OUTWARD, then to
    the lowest row and column.
    """
    from scipy import ndimage
    resolution = grid.resolution
    column, row = np.floor((entrance - grid.origin) / resolution).astype(int)
    box = _grown((slice(row, row + 1), slice(column, column + 1)), window, fits.shape)
    passage = in_passages[box]
    way = fits[box] & ~passage
    regions, _ = ndimage.label(way, structure=_EIGHT)
    rows, columns = np.nonzero(way)
    offsets = _world(grid, *_cells_in(way, box)) - entrance
    along = offsets @ outward
    across = offsets @ np.array([-outward[1], outward[0]])
    touching = ndimage.binary_dilation(passage, structure=_EIGHT)[rows, columns] & (along > 0.0)
    reached = np.isin(regions[rows, columns], regions[rows[touching], columns[touching]])
    # Distances from cell centres to passage cells' centres [m].
    away = ndimage.distance_transform_edt(~passage)[rows, columns] * resolution
    apart = 2.0 * radius + margin
    good = (reached & (clearance[box][rows, columns] >= radius + margin) & (along >= 0.0)
            & (away >= apart) & (np.abs(across) >= apart))
    # Only the spots within reach of the window: their number, not all of them, costs.
    others = np.reshape(taken, (-1, 2)) - entrance
    others = others[np.max(np.abs(others), axis=1) <= (window + 1) * resolution + apart]
    for other in others:
        good &= np.linalg.norm(offsets - other, axis=1) >= apart
    if not good.any():
        return None
    distances = np.round(np.hypot(*offsets[good].T) / resolution, 9)
    best = np.lexsort((columns[good], rows[good], across[good] > 0.0, distances))[0]
    return entrance + offsets[good][best]
