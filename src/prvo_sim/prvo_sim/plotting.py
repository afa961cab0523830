"""Trajectory figures of scenario runs, drawn with matplotlib's Agg backend (no display)."""

import matplotlib

matplotlib.use('Agg')

from matplotlib.patches import Circle  # noqa: E402  (the backend must be chosen first)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def robot_colours(count):
    """Return COUNT distinct colours, one per robot."""
    colour_map = plt.get_cmap('tab10' if count <= 10 else 'tab20')
    return [colour_map(index % colour_map.N) for index in range(count)]


def draw_trajectories(axes, times, positions, starts, goals, radii, contacts,
                      disc_interval=1.0, labels=None, yaws=None):
    """Draw paths, start (square) and goal (star) markers, discs every DISC_INTERVAL seconds.

    CONTACTS are (time, i, j, distance) events: both robots' positions at that time are marked
    with red crosses and red disc outlines. YAWS (T, N), if given, draws each disc's heading as
    a radius.
    """
    times = np.asarray(times, dtype=float)
    positions = np.asarray(positions, dtype=float)
    colours = robot_colours(positions.shape[1])
    disc_steps = _steps_every(times, disc_interval)
    for robot, colour in enumerate(colours):
        path = positions[:, robot, :]
        label = None if labels is None else labels[robot]
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


def _steps_every(times, interval):
    """Return the indices of TIMES closest to 0, INTERVAL, 2 INTERVAL, ... from times[0]."""
    if times.size == 0:
        return []
    marks = np.arange(times[0], times[-1] + 1e-9, interval)
    return sorted({int(np.argmin(np.abs(times - mark))) for mark in marks} | {times.size - 1})


def plot_run(path, times, positions, starts, goals, radii, robot_names, contacts, title,
             yaws=None):
    """Write a PNG of one run's trajectories to PATH (headings drawn where YAWS is given)."""
    figure, axes = plt.subplots(figsize=(7.0, 7.0))
    draw_trajectories(axes, times, positions, starts, goals, radii, contacts,
                      labels=list(robot_names), yaws=yaws)
    axes.set_title(title, fontsize=10)
    axes.legend(loc='upper left', fontsize=7, ncol=2, framealpha=0.7)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
