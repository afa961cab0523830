"""Trajectory figures of scenario runs, drawn with matplotlib's Agg backend (no display)."""

import matplotlib

matplotlib.use('Agg')

from matplotlib.patches import Circle  # noqa: E402  (the backend must be chosen first)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

SCRIPTED_COLOUR = 'grey'


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
             scripted=None, yaws=None):
    """Write a PNG of one run's trajectories to PATH (SCRIPTED, YAWS: see draw_trajectories)."""
    figure, axes = plt.subplots(figsize=(7.0, 7.0))
    draw_trajectories(axes, times, positions, starts, goals, radii, contacts,
                      labels=list(robot_names), scripted=scripted, yaws=yaws)
    axes.set_title(title, fontsize=10)
    axes.legend(loc='upper left', fontsize=7, ncol=2, framealpha=0.7)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
