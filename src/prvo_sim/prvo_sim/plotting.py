"""Trajectory figures of scenario runs, drawn with matplotlib's Agg backend (no display)."""

import matplotlib

matplotlib.use('Agg')

from matplotlib.colors import to_rgb  # noqa: E402  (the backend must be chosen first)
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Patch, Polygon  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from prvo_sim.turns import GOES, WAITS  # noqa: E402

SCRIPTED_COLOUR = 'grey'
STATIC_COLOUR = '#555560'
# Map cells (RGBA): unknown light grey; occupied dark, as opaque as its occupancy (free: clear).
_UNKNOWN_RGBA = (0.8, 0.8, 0.82, 0.6)
_OCCUPIED_RGB = (0.33, 0.33, 0.38)
# Points on each end's half circle of a drawn wall.
_CAP_POINTS = 12
# The right of way (Okabe-Ito colours, told apart also by those who confuse red and green):
# passages orange, a robot that holds one green, one waiting for its turn purple.
PASSAGE_COLOUR = '#e69f00'
GOES_COLOUR = '#009e73'
WAITS_COLOUR = '#cc79a7'
GOES_LABEL = 'holds a passage (goes)'
WAITS_LABEL = 'waits for its turn'


def robot_colours(count):
    """Return COUNT distinct colours, one per robot."""
    colour_map = plt.get_cmap('tab10' if count <= 10 else 'tab20')
    return [colour_map(index % colour_map.N) for index in range(count)]


def draw_trajectories(axes, times, positions, starts, goals, radii, contacts,
                      disc_interval=1.0, labels=None, scripted=None, yaws=None):
    """Draw paths, start (square) and goal (star) markers, discs every DISC_INTERVAL seconds.

    CONTACTS are (time, i, j, distance) events: both robots' positions at that time are marked
    with red crosses and red disc outlines. SCRIPTED (N,) marks robots that follow waypoints:
    a dashed grey path, hatched grey discs, no goal star, '(scripted)' in their label. YAWS
    (T, N), if given, draws each disc's heading as a radius.
    """
    times = np.asarray(times, dtype=float)
    positions = np.asarray(positions, dtype=float)
    scripted = np.zeros(positions.shape[1], dtype=bool) if scripted is None else scripted
    colours = robot_colours(int(np.count_nonzero(np.logical_not(scripted))))[::-1]
    disc_steps = _steps_every(times, disc_interval)
    for robot in range(positions.shape[1]):
        path = positions[:, robot, :]
        label = None if labels is None else labels[robot]
        if scripted[robot]:
            _draw_scripted(axes, path, starts[robot], radii[robot], disc_steps,
                           None if label is None else f'{label} (scripted)')
            continue
        colour = colours.pop()
        axes.plot(path[:, 0], path[:, 1], '-', color=colour, linewidth=1.2, label=label)
        for step in disc_steps:
            axes.add_patch(Circle(path[step], radii[robot], fill=False, color=colour,
                                  alpha=0.35, linewidth=0.8))
            if yaws is not None:
                heading = radii[robot] * np.array([np.cos(yaws[step, robot]),
                                                   np.sin(yaws[step, robot])])
                axes.plot(*np.stack([path[step], path[step] + heading], axis=1), '-',
                          color=colour, alpha=0.6, linewidth=0.8)
        axes.plot(*starts[robot], 's', color=colour, markersize=7)
        axes.plot(*goals[robot], '*', color=colour, markersize=12, markeredgecolor='black',
                  markeredgewidth=0.5)
    for contact_time, first, second, _distance in contacts:
        step = int(np.argmin(np.abs(times - contact_time)))
        for robot in (first, second):
            axes.add_patch(Circle(positions[step, robot], radii[robot], fill=False,
                                  color='red', linewidth=1.5))
            axes.plot(*positions[step, robot], 'x', color='red', markersize=8)
    axes.set_aspect('equal')
    axes.set_xlabel('x [m]')
    axes.set_ylabel('y [m]')
    axes.grid(True, alpha=0.3)


def draw_static_world(axes, static_world):
    """Draw STATIC_WORLD's map cells, walls (their capsules), disc and polygon obstacles.

    Drawn below the robots. Nothing for a world without static shapes.
    """
    if static_world is None or static_world.empty:
        return
    grid = static_world.map_grid
    if grid is not None:
        height, width = grid.shape
        low = grid.origin
        high = low + grid.resolution * np.array([width, height])
        shown = np.zeros((height, width, 4))
        shown[..., :3] = _OCCUPIED_RGB
        shown[..., 3] = np.maximum(grid.cells, 0) / 100.0
        shown[grid.cells < 0] = _UNKNOWN_RGBA
        axes.imshow(shown, origin='lower', extent=(low[0], high[0], low[1], high[1]),
                    interpolation='nearest', zorder=0)
    for line, thickness in static_world.walls:
        if thickness == 0.0:
            axes.plot(line[:, 0], line[:, 1], '-', color=STATIC_COLOUR, linewidth=2.0,
                      zorder=1)
            continue
        axes.add_patch(Polygon(_capsule_outline(line, 0.5 * thickness), closed=True,
                               color=STATIC_COLOUR, zorder=1))
    for centre, radius in static_world.discs:
        axes.add_patch(Circle(centre, radius, color=STATIC_COLOUR, zorder=1))
    for vertices in static_world.polygons:
        axes.add_patch(Polygon(vertices, closed=True, color=STATIC_COLOUR, zorder=1))


def draw_passages(axes, turns):
    """Draw the passages of TURNS (`turns.Turns`): their cells, shaded and outlined.

    Each end's waiting spot is a hollow dot. Returns the legend's handles of what is drawn
    (none without a passage).
    """
    for shape in turns.shapes:
        mask, extent = shape.mask()
        shown = np.zeros((*mask.shape, 4))
        shown[mask] = (*to_rgb(PASSAGE_COLOUR), 0.35)
        axes.imshow(shown, origin='lower', extent=extent, interpolation='nearest', zorder=0.5)
        # Sampled at the cells' centres, the level halfway between a passage cell and its
        # neighbour outside lies on the edge between them: the outline of the cells.
        x0, x1, y0, y1 = extent
        rows, columns = mask.shape
        half = 0.5 * shape.resolution
        axes.contour(np.linspace(x0 + half, x1 - half, columns),
                     np.linspace(y0 + half, y1 - half, rows), mask.astype(float),
                     levels=[0.5], colors=PASSAGE_COLOUR, linewidths=1.0, zorder=0.6)
        for end in shape.passage.ends:
            if end.waiting_spot is not None:
                axes.plot(*end.waiting_spot, 'o', markerfacecolor='none',
                          markeredgecolor=PASSAGE_COLOUR, markersize=6, zorder=0.6)
    if not turns.shapes:
        return []
    return [Patch(facecolor=PASSAGE_COLOUR, alpha=0.35, edgecolor=PASSAGE_COLOUR,
                  label='passage (o: waiting spots)')]


def turn_handles(rings=False):
    """Return the legend's handles of a robot that goes and one that waits.

    As `draw_turns` marks them, or with RINGS as the animation does.
    """
    if rings:
        return [Line2D([], [], linestyle=style, color=colour, label=label)
                for style, colour, label in (('-', GOES_COLOUR, GOES_LABEL),
                                             ('--', WAITS_COLOUR, WAITS_LABEL))]
    return [Line2D([], [], linestyle='none', marker=marker, markerfacecolor=colour,
                   markeredgecolor='black', markeredgewidth=0.5, label=label)
            for marker, colour, label in (('^', GOES_COLOUR, GOES_LABEL),
                                          ('s', 'white', WAITS_LABEL))]


def draw_turns(axes, times, positions, turns, interval=0.5):
    """Draw the passages of TURNS and, on POSITIONS (T, N, 2), who went and who waited.

    Every INTERVAL [s] of TIMES (T,) a robot that holds a passage (goes) is marked with a green
    triangle, one that waits for its turn with a white square, edged in black so as not to be
    taken for a robot's colour. Returns the legend's handles (none if no robot went or
    waited).
    """
    handles = draw_passages(axes, turns)
    steps = np.array(_steps_every(np.asarray(times, dtype=float), interval), dtype=int)
    for state, handle in zip((GOES, WAITS), turn_handles(), strict=True):
        marked, robots = np.nonzero(turns.states[steps] == state)
        axes.plot(positions[steps[marked], robots, 0], positions[steps[marked], robots, 1],
                  linestyle='none', marker=handle.get_marker(),
                  markerfacecolor=handle.get_markerfacecolor(), markeredgecolor='black',
                  markeredgewidth=0.5, markersize=4.5, alpha=0.8, zorder=2.5)
    if not np.any(turns.states):
        return handles
    return handles + turn_handles()


def static_world_bounds(static_world):
    """Return (low (2,), high (2,)) of what draw_static_world draws, or None if nothing."""
    if static_world is None or static_world.empty:
        return None
    grid = static_world.grid
    return grid.origin, grid.origin + grid.resolution * np.array(grid.shape[::-1])


def _capsule_outline(line, half_width):
    """Return the (2 _CAP_POINTS, 2) outline of the points within HALF_WIDTH of LINE (2, 2)."""
    start, end = line
    angle = np.arctan2(*(end - start)[::-1])
    caps = []
    for centre, facing in ((end, angle), (start, angle + np.pi)):
        turns = facing + np.linspace(-0.5 * np.pi, 0.5 * np.pi, _CAP_POINTS)
        caps.append(centre + half_width * np.stack([np.cos(turns), np.sin(turns)], axis=1))
    return np.vstack(caps)


def _draw_scripted(axes, path, start, radius, disc_steps, label):
    """Draw a scripted robot: dashed grey PATH, hatched grey discs, grey start square."""
    axes.plot(path[:, 0], path[:, 1], '--', color=SCRIPTED_COLOUR, linewidth=1.2, label=label)
    for step in disc_steps:
        axes.add_patch(Circle(path[step], radius, fill=False, color=SCRIPTED_COLOUR, alpha=0.5,
                              linewidth=0.8, hatch='///'))
    axes.plot(*start, 's', color=SCRIPTED_COLOUR, markersize=7)


def _steps_every(times, interval):
    """Return the indices of TIMES closest to 0, INTERVAL, 2 INTERVAL, ... from times[0]."""
    if times.size == 0:
        return []
    marks = np.arange(times[0], times[-1] + 1e-9, interval)
    return sorted({int(np.argmin(np.abs(times - mark))) for mark in marks} | {times.size - 1})


def plot_run(path, times, positions, starts, goals, radii, robot_names, contacts, title,
             scripted=None, yaws=None, static_world=None, turns=None):
    """Write a PNG of one run's trajectories to PATH (SCRIPTED, YAWS: see draw_trajectories).

    STATIC_WORLD (`prvo_sim.static_world.StaticWorld`), if given, is drawn under them; TURNS
    (`prvo_sim.turns.Turns`), if given, the passages and who held them (`draw_turns`).
    """
    figure, axes = plt.subplots(figsize=(7.0, 7.0))
    draw_static_world(axes, static_world)
    positions = np.asarray(positions, dtype=float)
    turn_legend = [] if turns is None else draw_turns(axes, times, positions, turns)
    draw_trajectories(axes, times, positions, starts, goals, radii, contacts,
                      labels=list(robot_names), scripted=scripted, yaws=yaws)
    axes.set_title(title, fontsize=10)
    handles, _ = axes.get_legend_handles_labels()
    axes.legend(handles=handles + turn_legend, loc='upper left', fontsize=7, ncol=2,
                framealpha=0.7)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
