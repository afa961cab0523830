"""The static part of a scenario's world, ROS-free: walls, solid obstacles and a map's cells.

Every shape is a closed set in the world frame [m]:

* a wall is the capsule of points within half its thickness of a segment [a, b];
* a disc obstacle, a centre and a radius;
* a polygon obstacle, solid (its interior and edges), simple (no edges crossing);
* a map's solid cells, the axis-aligned squares whose value is occupied (100).

A robot (a disc of radius r) touches a shape when its centre comes within r of it. For the
robot's motion the world keeps one list of capsules: the walls, every polygon edge (half-width
0) and the boundary of the map's solid region (merged runs of cell edges, half-width 0); a
robot that starts outside a solid shape can enter it only through its boundary, so the first
time a straight motion comes within r of a capsule or a disc is its first contact. The
rasterised grid (`StaticWorld.grid`) is the whole static world as one occupancy grid.
"""

import functools
import math

import numpy as np

from prvo_planner.maps import FREE, OCCUPIED, UNKNOWN, GridMap

# Cell edge of the rasterised grid when no map file sets it [m].
DEFAULT_RESOLUTION = 0.05
# Free cells around the shapes, the robots' starts and goals in a grid without a map file [m].
GRID_MARGIN = 1.0
# A robot whose clearance is at most this is in contact [m]: stopped at a surface, rounding
# leaves it within a few ulps of it, on either side.
CONTACT_TOLERANCE = 1e-9
# A cell counts as touched by a shape within this distance of it [m]: rounding never leaves a
# touched cell free (the rasterisation errs on the occupied side).
_RASTER_SLACK = 1e-9
# Points per chunk of a clearance computation: bounds its temporary arrays.
_CHUNK = 4096


def point_segment_distances(points, segments):
    """Return the (P, K) distances from POINTS (P, 2) to SEGMENTS (K, 2, 2) [m]."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    starts, ends = segments[:, 0], segments[:, 1]
    along = ends - starts
    length_sq = np.einsum('ij,ij->i', along, along)
    offsets = points[:, None, :] - starts[None]
    fraction = np.clip(np.einsum('pkj,kj->pk', offsets, along) / length_sq, 0.0, 1.0)
    return np.linalg.norm(offsets - fraction[..., None] * along[None], axis=-1)


def points_in_polygon(points, vertices):
    """Return (P,) bools: whether each of POINTS (P, 2) lies strictly inside VERTICES (V, 2).

    Even-odd rule; a point on an edge may come out either way (its distance to the edge is 0).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    x, y = points[:, 0:1], points[:, 1:2]
    first, second = vertices, np.roll(vertices, -1, axis=0)
    straddles = (first[:, 1] > y) != (second[:, 1] > y)
    with np.errstate(divide='ignore', invalid='ignore'):
        crossing_x = first[:, 0] + (y - first[:, 1]) * (second[:, 0] - first[:, 0]) / (
            second[:, 1] - first[:, 1])
    return np.count_nonzero(straddles & (x < crossing_x), axis=1) % 2 == 1


def solid_boundary(solid, resolution, origin):
    """Return the (K, 2, 2) segments bounding the True cells of SOLID (H, W), merged runs.

    Every edge between a solid cell and a non-solid one or the grid's outside, joined into
    maximal straight runs; cell (row, column) spans origin + resolution * [column, column + 1]
    x [row, row + 1].
    """
    padded = np.pad(np.asarray(solid, dtype=bool), 1)
    segments = []
    # Horizontal edges: between rows r - 1 and r of the padded grid (y = origin + (r-1) res).
    horizontal = padded[1:, 1:-1] != padded[:-1, 1:-1]
    for row, start, stop in _runs(horizontal):
        y = origin[1] + row * resolution
        segments.append([[origin[0] + start * resolution, y], [origin[0] + stop * resolution, y]])
    vertical = padded[1:-1, 1:] != padded[1:-1, :-1]
    for column, start, stop in _runs(vertical.T):
        x = origin[0] + column * resolution
        segments.append([[x, origin[1] + start * resolution], [x, origin[1] + stop * resolution]])
    return np.array(segments, dtype=float).reshape(-1, 2, 2)


def _runs(mask):
    """Return (line, start, stop) of every maximal run of True along each row of MASK."""
    padded = np.pad(mask, ((0, 0), (1, 1)))
    changes = np.diff(padded.astype(np.int8), axis=1)
    lines, starts = np.nonzero(changes == 1)
    _, stops = np.nonzero(changes == -1)
    return zip(lines.tolist(), starts.tolist(), stops.tolist(), strict=True)


class StaticWorld:
    """The walls, obstacles and map of a scenario, with the geometry the simulator needs.

    Parameters
    ----------
    walls : sequence of (numpy.ndarray (2, 2), float)
        Each wall's segment [[x1, y1], [x2, y2]] [m] (ends distinct) and thickness [m] (>= 0).
    discs : sequence of (numpy.ndarray (2,), float)
        Each disc obstacle's centre [m] and radius [m] (> 0).
    polygons : sequence of numpy.ndarray (V, 2)
        Each solid polygon's vertices [m], V >= 3, edges not crossing.
    map_grid : prvo_planner.maps.GridMap or None
        The map file's grid, or None.
    extent_points : array_like (P, 2)
        Points the rasterised grid must also cover (the robots' starts and goals) [m].

    Attributes: `walls`, `discs`, `polygons`, `map_grid` as given; `segments` (K, 2, 2) and
    `half_widths` (K,): the capsules a robot must keep its radius from (walls, polygon edges,
    the map's solid boundary); `disc_centres` (M, 2), `disc_radii` (M,); `grid`, the
    rasterised `GridMap` of the whole static world (None for a world with no static shape),
    built when first asked for.
    """

    def __init__(self, walls=(), discs=(), polygons=(), map_grid=None,
                 extent_points=()):
        self.walls = tuple((np.array(line, dtype=float), float(thickness))
                           for line, thickness in walls)
        self.discs = tuple((np.array(centre, dtype=float), float(radius))
                           for centre, radius in discs)
        self.polygons = tuple(np.array(vertices, dtype=float) for vertices in polygons)
        self.map_grid = map_grid
        self.map_solid = None if map_grid is None else map_grid.cells == OCCUPIED
        segments = [line for line, _ in self.walls]
        half_widths = [0.5 * thickness for _, thickness in self.walls]
        for vertices in self.polygons:
            edges = np.stack([vertices, np.roll(vertices, -1, axis=0)], axis=1)
            segments += list(edges)
            half_widths += [0.0] * len(edges)
        if map_grid is not None:
            boundary = solid_boundary(self.map_solid, map_grid.resolution, map_grid.origin)
            segments += list(boundary)
            half_widths += [0.0] * len(boundary)
        self.segments = np.array(segments, dtype=float).reshape(-1, 2, 2)
        self.half_widths = np.array(half_widths, dtype=float)
        self.disc_centres = np.array([centre for centre, _ in self.discs]).reshape(-1, 2)
        self.disc_radii = np.array([radius for _, radius in self.discs], dtype=float)
        self._extent_points = np.asarray(extent_points, dtype=float).reshape(-1, 2)

    @property
    def empty(self):
        """Whether the world has no static shape at all."""
        return not (self.walls or self.discs or self.polygons or self.map_grid is not None)

    def clearance(self, points):
        """Return the (P,) signed distances of POINTS (P, 2) to the nearest static shape [m].

        Positive outside every shape, 0 on a surface, negative inside one (minus the depth to
        its boundary); +inf in a world with no shape.
        """
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        result = np.full(len(points), np.inf)
        for start in range(0, len(points), _CHUNK):
            chunk = points[start:start + _CHUNK]
            nearest = np.full(len(chunk), np.inf)
            if len(self.segments):
                nearest = np.minimum(nearest, (point_segment_distances(chunk, self.segments)
                                               - self.half_widths).min(axis=1))
            if len(self.disc_radii):
                nearest = np.minimum(nearest, (np.linalg.norm(
                    chunk[:, None] - self.disc_centres[None], axis=-1) - self.disc_radii).min(
                    axis=1))
            inside = self._inside_solid(chunk)
            result[start:start + _CHUNK] = np.where(inside, -np.abs(nearest), nearest)
        return result

    def _inside_solid(self, points):
        """Return (P,) bools: inside a polygon or a solid map cell (boundaries excepted)."""
        inside = np.zeros(len(points), dtype=bool)
        for vertices in self.polygons:
            inside |= points_in_polygon(points, vertices)
        if self.map_grid is not None:
            cell = np.floor((points - self.map_grid.origin) / self.map_grid.resolution)
            height, width = self.map_solid.shape
            within = ((cell >= 0) & (cell < [width, height])).all(axis=1)
            rows, columns = cell[within, 1].astype(int), cell[within, 0].astype(int)
            inside[np.flatnonzero(within)] |= self.map_solid[rows, columns]
        return inside

    def first_contact(self, start, motion, radius):
        """Return (fraction, normal) of a disc's first contact moving from START by MOTION.

        START (2,) is a centre at least RADIUS from every shape [m], MOTION (2,) the step's
        displacement [m]. FRACTION in [0, 1] is how far along MOTION the disc first touches a
        shape and NORMAL (2,) the unit vector from the shape's nearest point to the centre
        there; (None, None) if the whole motion is free. A disc touching a shape at START and
        moving into it has fraction 0.
        """
        start = np.asarray(start, dtype=float)
        motion = np.asarray(motion, dtype=float)
        best = math.inf
        if len(self.disc_radii):
            best = min(best, _circle_hit(start, motion, self.disc_centres,
                                         self.disc_radii + radius))
        if len(self.segments):
            reach = self.half_widths + radius
            # Only capsules the motion's bounding box comes near can be hit.
            low = np.minimum(start, start + motion)
            high = np.maximum(start, start + motion)
            near = ((self.segments.min(axis=1) <= high + reach[:, None])
                    & (self.segments.max(axis=1) >= low - reach[:, None])).all(axis=1)
            if near.any():
                best = min(best, _capsule_hit(start, motion, self.segments[near], reach[near]))
        if best > 1.0:
            return None, None
        point = start + best * motion
        nearest, reach = self._nearest_points(point)
        gap = point[None] - nearest
        distances = np.linalg.norm(gap, axis=1)
        touched = int(np.argmin(distances - reach))
        return best, gap[touched] / max(float(distances[touched]), 1e-300)

    def _nearest_points(self, point):
        """Return (K + M, 2) nearest points of every segment and disc centre to POINT, reaches.

        The reach (K + M,) of each is how far its surface lies from it: the half-width of a
        capsule, the radius of a disc.
        """
        nearest, reach = [], []
        if len(self.segments):
            starts, along = self.segments[:, 0], self.segments[:, 1] - self.segments[:, 0]
            fraction = np.clip(np.einsum('kj,kj->k', point - starts, along)
                               / np.einsum('kj,kj->k', along, along), 0.0, 1.0)
            nearest.append(starts + fraction[:, None] * along)
            reach.append(self.half_widths)
        if len(self.disc_radii):
            nearest.append(self.disc_centres)
            reach.append(self.disc_radii)
        return np.vstack(nearest), np.concatenate(reach)

    def move(self, start, motion, radius):
        """Return (end, touched): where a disc at START ends moving by MOTION, and if it hit.

        Up to the first contact the disc moves freely; there the part of its remaining motion
        into the shape (along the contact normal) is removed and the rest, along the surface,
        is moved as far as it is free. The disc never comes closer than RADIUS to a shape (up
        to rounding).
        """
        start = np.asarray(start, dtype=float)
        motion = np.asarray(motion, dtype=float)
        fraction, normal = self.first_contact(start, motion, radius)
        if fraction is None:
            return start + motion, False
        contact = start + fraction * motion
        rest = (1.0 - fraction) * motion
        rest = rest - min(float(rest @ normal), 0.0) * normal
        slide, _ = self.first_contact(contact, rest, radius)
        return contact + (1.0 if slide is None else slide) * rest, True

    def grid_layout(self):
        """Return (first cell (2,) int, (height, width), resolution) of the rasterised grid.

        The grid's cells lie on the lattice of the map file's cells (else of the world origin,
        DEFAULT_RESOLUTION apart); FIRST is the lattice index (column, row) of its cell (0, 0).
        It covers the map file's cells and every shape, and without a map file also the extent
        points, GRID_MARGIN around.
        """
        if self.map_grid is not None:
            resolution, origin = self.map_grid.resolution, self.map_grid.origin
        else:
            resolution, origin = DEFAULT_RESOLUTION, np.zeros(2)
        low, high = self._shape_bounds()
        if self.map_grid is None:
            points = self._extent_points
            low = np.minimum(low, points.min(axis=0, initial=np.inf)) - GRID_MARGIN
            high = np.maximum(high, points.max(axis=0, initial=-np.inf)) + GRID_MARGIN
            first = np.floor((low - origin) / resolution - _RASTER_SLACK).astype(int)
            last = np.ceil((high - origin) / resolution + _RASTER_SLACK).astype(int)
        else:
            first, last = np.zeros(2, dtype=int), np.array(self.map_grid.shape[::-1])
            if np.isfinite(low).all():
                first = np.minimum(first, np.floor((low - origin) / resolution
                                                   - _RASTER_SLACK).astype(int))
                last = np.maximum(last, np.ceil((high - origin) / resolution
                                                + _RASTER_SLACK).astype(int))
        width, height = (last - first).tolist()
        return first, (height, width), resolution

    @functools.cached_property
    def grid(self):
        """The GridMap of every static shape over the map file's cells (None: no shape)."""
        if self.empty:
            return None
        first, (height, width), resolution = self.grid_layout()
        origin = np.zeros(2) if self.map_grid is None else self.map_grid.origin
        grid_origin = origin + first * resolution
        cells = np.full((height, width), FREE if self.map_grid is None else UNKNOWN,
                        dtype=np.int8)
        if self.map_grid is not None:
            rows, columns = self.map_grid.shape
            cells[-first[1]:-first[1] + rows, -first[0]:-first[0] + columns] = \
                self.map_grid.cells
        for line, thickness in self.walls:
            _mark_near_segment(cells, grid_origin, resolution, line, 0.5 * thickness)
        for centre, radius in self.discs:
            _mark_near_disc(cells, grid_origin, resolution, centre, radius)
        for vertices in self.polygons:
            for edge in np.stack([vertices, np.roll(vertices, -1, axis=0)], axis=1):
                _mark_near_segment(cells, grid_origin, resolution, edge, 0.0)
            _mark_inside_polygon(cells, grid_origin, resolution, vertices)
        return GridMap(cells, resolution, grid_origin)

    def _shape_bounds(self):
        """Return (low (2,), high (2,)) of the walls', discs', polygons' points (+-inf: none)."""
        low, high = np.full(2, np.inf), np.full(2, -np.inf)
        for line, thickness in self.walls:
            low = np.minimum(low, line.min(axis=0) - 0.5 * thickness)
            high = np.maximum(high, line.max(axis=0) + 0.5 * thickness)
        for centre, radius in self.discs:
            low, high = np.minimum(low, centre - radius), np.maximum(high, centre + radius)
        for vertices in self.polygons:
            low = np.minimum(low, vertices.min(axis=0))
            high = np.maximum(high, vertices.max(axis=0))
        return low, high


def _circle_hit(start, motion, centres, reach):
    """Return the smallest fraction in [0, inf] at which START + t MOTION enters a circle.

    CENTRES (M, 2), REACH (M,) their radii; inf if none is entered for t >= 0. A point on or
    inside a circle moving inward enters it at 0.
    """
    offset = start - centres
    a = float(motion @ motion)
    b = offset @ motion
    c = np.einsum('mj,mj->m', offset, offset) - reach ** 2
    hits = np.full(len(reach), np.inf)
    inward = b < 0.0
    hits[inward & (c <= 0.0)] = 0.0
    discriminant = b * b - a * c
    crossing = inward & (c > 0.0) & (discriminant >= 0.0)
    hits[crossing] = (-b[crossing] - np.sqrt(discriminant[crossing])) / a
    return float(hits.min(initial=np.inf))


def _capsule_hit(start, motion, segments, reach):
    """Return the smallest fraction at which START + t MOTION comes within REACH of SEGMENTS.

    SEGMENTS (K, 2, 2), REACH (K,); inf if none. A capsule is the union of its end discs and
    the rectangle between them: its first entry is the first of its end discs' and of the
    rectangle's long sides (an entry through a short side lies in an end disc).
    """
    best = min(_circle_hit(start, motion, segments[:, 0], reach),
               _circle_hit(start, motion, segments[:, 1], reach))
    along = segments[:, 1] - segments[:, 0]
    length = np.linalg.norm(along, axis=1)
    unit = along / length[:, None]
    across = np.stack([-unit[:, 1], unit[:, 0]], axis=1)
    offset = start - segments[:, 0]
    zeta = np.einsum('kj,kj->k', offset, across)
    xi = np.einsum('kj,kj->k', offset, unit)
    dzeta, dxi = across @ motion, unit @ motion
    # The side facing the start: zeta = +reach above the segment's line, -reach below.
    side = np.where(zeta >= 0.0, 1.0, -1.0)
    height = side * zeta - reach  # distance to the facing side, <= 0 once at or past it
    approach = -side * dzeta  # speed towards the line
    hits = np.full(len(reach), np.inf)
    moving = approach > 0.0
    time = np.maximum(height[moving], 0.0) / approach[moving]
    at = xi[moving] + time * dxi[moving]
    within = (at >= 0.0) & (at <= length[moving])
    hits[np.flatnonzero(moving)[within]] = time[within]
    return min(best, float(hits.min(initial=np.inf)))


def _cell_window(cells, origin, resolution, low, high):
    """Return (rows, columns, lower-left corners (h, w, 2)) of the cells meeting [LOW, HIGH]."""
    height, width = cells.shape
    first = np.floor((low - origin) / resolution - _RASTER_SLACK).astype(int)
    last = np.floor((high - origin) / resolution + _RASTER_SLACK).astype(int)
    columns = np.arange(max(first[0], 0), min(last[0], width - 1) + 1)
    rows = np.arange(max(first[1], 0), min(last[1], height - 1) + 1)
    corners = origin + resolution * np.stack(np.meshgrid(columns, rows), axis=-1)
    return rows, columns, corners


def _box_segment_distances(corners, resolution, segment):
    """Return the (h, w) distances between cells (lower-left CORNERS) and SEGMENT (2, 2).

    Exact: 0 where the segment meets the closed square, else the least distance between an
    end of the segment and the square or a corner of the square and the segment (two disjoint
    convex sets are nearest at a vertex of one).
    """
    start, end = segment
    low, high = corners, corners + resolution
    # Clip the segment to each square (slab method): it meets it if an interval is left.
    direction = end - start
    entry, leave = np.zeros(corners.shape[:2]), np.ones(corners.shape[:2])
    for axis in range(2):
        if direction[axis] == 0.0:
            outside = (start[axis] < low[..., axis]) | (start[axis] > high[..., axis])
            leave = np.where(outside, -1.0, leave)
            continue
        first = (low[..., axis] - start[axis]) / direction[axis]
        second = (high[..., axis] - start[axis]) / direction[axis]
        entry = np.maximum(entry, np.minimum(first, second))
        leave = np.minimum(leave, np.maximum(first, second))
    meets = entry <= leave
    ends = np.stack([start, end])
    nearest_to_end = np.clip(ends[:, None, None, :], low[None], high[None])
    end_gap = np.linalg.norm(ends[:, None, None, :] - nearest_to_end, axis=-1).min(axis=0)
    offsets = np.array([[0.0, 0.0], [resolution, 0.0], [0.0, resolution],
                        [resolution, resolution]])
    points = (corners[..., None, :] + offsets).reshape(-1, 2)
    corner_gap = point_segment_distances(points, segment[None]).reshape(
        *corners.shape[:2], 4).min(axis=-1)
    return np.where(meets, 0.0, np.minimum(end_gap, corner_gap))


def _mark_near_segment(cells, origin, resolution, segment, half_width):
    """Set to occupied every cell within HALF_WIDTH of SEGMENT (2, 2)."""
    reach = half_width + _RASTER_SLACK
    rows, columns, corners = _cell_window(cells, origin, resolution,
                                          segment.min(axis=0) - reach,
                                          segment.max(axis=0) + reach)
    if rows.size and columns.size:
        near = _box_segment_distances(corners, resolution, segment) <= reach
        window = cells[rows[0]:rows[-1] + 1, columns[0]:columns[-1] + 1]
        window[near] = OCCUPIED


def _mark_near_disc(cells, origin, resolution, centre, radius):
    """Set to occupied every cell that the disc (CENTRE, RADIUS) meets."""
    reach = radius + _RASTER_SLACK
    rows, columns, corners = _cell_window(cells, origin, resolution, centre - reach,
                                          centre + reach)
    if rows.size and columns.size:
        nearest = np.clip(centre, corners, corners + resolution)
        near = np.linalg.norm(nearest - centre, axis=-1) <= reach
        cells[rows[0]:rows[-1] + 1, columns[0]:columns[-1] + 1][near] = OCCUPIED


def _mark_inside_polygon(cells, origin, resolution, vertices):
    """Set to occupied every cell whose centre lies inside the polygon VERTICES (V, 2).

    A cell the polygon meets either holds a point of an edge (marked by the edges) or lies
    wholly inside it, centre included.
    """
    rows, columns, corners = _cell_window(cells, origin, resolution, vertices.min(axis=0),
                                          vertices.max(axis=0))
    if rows.size and columns.size:
        centres = (corners + 0.5 * resolution).reshape(-1, 2)
        inside = points_in_polygon(centres, vertices).reshape(corners.shape[:2])
        cells[rows[0]:rows[-1] + 1, columns[0]:columns[-1] + 1][inside] = OCCUPIED


def segments_cross(first, second):
    """Return whether segments FIRST and SECOND (2, 2) share a point."""
    def orientation(a, b, c):
        value = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        return 0 if value == 0.0 else (1 if value > 0.0 else -1)

    def on_segment(a, b, c):
        return (min(a[0], b[0]) <= c[0] <= max(a[0], b[0])
                and min(a[1], b[1]) <= c[1] <= max(a[1], b[1]))

    p, q = first
    r, s = second
    o1, o2, o3, o4 = (orientation(p, q, r), orientation(p, q, s), orientation(r, s, p),
                      orientation(r, s, q))
    if o1 != o2 and o3 != o4:
        return True
    return ((o1 == 0 and on_segment(p, q, r)) or (o2 == 0 and on_segment(p, q, s))
            or (o3 == 0 and on_segment(r, s, p)) or (o4 == 0 and on_segment(r, s, q)))


def polygon_crossing(vertices):
    """Return (i, j, how) of two edges of the polygon VERTICES (V, 2) that meet, or None.

    Edge i runs from vertex i to vertex i + 1 (the last back to the first); neighbouring edges
    share their common vertex only. HOW is 'overlap' for neighbouring edges folding back onto
    each other, 'cross' for other edges that touch or cross.
    """
    count = len(vertices)
    edges = [(vertices[index], vertices[(index + 1) % count]) for index in range(count)]
    for i in range(count):
        for j in range(i + 1, count):
            neighbours = j == i + 1 or (i == 0 and j == count - 1)
            if neighbours:
                # Adjacent edges share one vertex; they overlap if they fold back onto each
                # other (collinear, their other ends on the same side of it).
                shared = edges[i][1] if j == i + 1 else edges[i][0]
                mine = edges[i][0] if j == i + 1 else edges[i][1]
                theirs = edges[j][1] if j == i + 1 else edges[j][0]
                u, w = mine - shared, theirs - shared
                if u[0] * w[1] - u[1] * w[0] == 0.0 and float(u @ w) > 0.0:
                    return i, j, 'overlap'
                continue
            if segments_cross(np.array(edges[i]), np.array(edges[j])):
                return i, j, 'cross'
    return None
