"""An animated GIF of a run: robots as discs moving over their paths, drawn with matplotlib.

Each frame shows every robot as a disc with, where known, a halo of its position uncertainty
and a line along its heading; robots in contact flash red; the sim time is in the corner. With
the run's right of way (`prvo_sim.turns.Turns`) the passages are shaded, a robot that holds one
has a green ring, one waiting for its turn a dashed purple ring, and a line per passage names
them.
Long runs are subsampled to at most MAX_FRAMES frames, played at the run's own pace.
"""

import math

import matplotlib

matplotlib.use('Agg')

from matplotlib.animation import PillowWriter  # noqa: E402  (the backend must be chosen first)
from matplotlib.patches import Circle  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from prvo_sim.metrics import pair_indices, pairwise_separation  # noqa: E402
from prvo_sim.plotting import (  # noqa: E402
    GOES_COLOUR,
    WAITS_COLOUR,
    draw_passages,
    draw_static_world,
    robot_colours,
    static_world_bounds,
    turn_handles,
)
from prvo_sim.turns import GOES, WAITS  # noqa: E402

MAX_FRAMES = 150  # keeps every shipped scenario's GIF far under 5 MB
MAX_FPS = 20.0  # a faster run is shown at this rate (fewer frames per sim second instead)
FIGURE_INCHES = 5.0
DPI = 80
UNCERTAINTY_SIGMAS = 2.0  # the halo's reach beyond the disc, in position standard deviations
FLASH_COLOURS = ('red', 'gold')  # a contact's ring alternates between these, frame by frame
TURN_RING = 1.5  # a right of way ring's radius, in the robot's radii: outside a contact's
TURN_STYLES = {GOES: (GOES_COLOUR, '-'), WAITS: (WAITS_COLOUR, '--')}  # colour, line style


def frame_steps(step_count, max_frames=MAX_FRAMES):
    """Return the steps drawn: every k-th of STEP_COUNT from the first, and the last.

    k is the smallest stride that gives at most MAX_FRAMES frames.
    """
    if step_count == 0:
        return np.zeros(0, dtype=int)
    stride = max(1, math.ceil((step_count - 1) / max(max_frames - 1, 1)))
    steps = np.arange(0, step_count, stride)
    if steps[-1] != step_count - 1:
        steps = np.append(steps, step_count - 1)
    return steps


def contact_frames(positions, radii, steps):
    """Return (frames, N) bools: robot in contact at any step since the previous frame's."""
    robot_count = positions.shape[1]
    in_contact = np.zeros((len(steps), robot_count), dtype=bool)
    if robot_count < 2 or len(steps) == 0:
        return in_contact
    touching = pairwise_separation(positions, radii) < 0.0
    first, second = pair_indices(robot_count)
    previous = 0
    for frame, step in enumerate(steps):
        pairs = touching[previous:step + 1].any(axis=0)
        in_contact[frame, first[pairs]] = True
        in_contact[frame, second[pairs]] = True
        previous = step + 1
    return in_contact


def animate_run(path, times, states, goals, radii, robot_names, title, position_std=None,
                scripted=None, max_frames=MAX_FRAMES, static_world=None, turns=None):
    """Write the GIF of one run to PATH; return the number of frames.

    TIMES (T,) [s]; STATES (T, N, 4 or more) ground truth x, y, vx, vy, and yaw [rad] where a
    fifth column holds it (headings are drawn then); GOALS (N, 2); RADII (N,). POSITION_STD
    (N,) [m], where known, draws each robot's uncertainty halo; SCRIPTED (N,) bools marks
    robots that follow a script rather than plan (drawn hatched, in grey outline);
    STATIC_WORLD (`prvo_sim.static_world.StaticWorld`), if given, is drawn under every frame;
    TURNS (`prvo_sim.turns.Turns`), if given, who holds each passage and who waits.
    """
    times = np.asarray(times, dtype=float)
    states = np.asarray(states, dtype=float)
    positions = states[..., :2]
    robot_count = positions.shape[1]
    steps = frame_steps(len(times), max_frames)
    flashing = contact_frames(positions, radii, steps)
    scripted = np.zeros(robot_count, dtype=bool) if scripted is None else np.asarray(scripted)
    colours = robot_colours(robot_count)
    figure, axes = plt.subplots(figsize=(FIGURE_INCHES, FIGURE_INCHES), dpi=DPI)
    _set_limits(axes, positions, goals, radii, static_world_bounds(static_world))
    draw_static_world(axes, static_world)
    turn_legend = [] if turns is None else draw_passages(axes, turns)
    axes.set_aspect('equal')
    axes.grid(True, alpha=0.3)
    axes.set_title(title, fontsize=8)
    discs, halos, headings, trails, rings, turn_rings = [], [], [], [], [], []
    for robot, colour in enumerate(colours):
        axes.plot(positions[:, robot, 0], positions[:, robot, 1], '-', color=colour,
                  alpha=0.2, linewidth=0.8)
        axes.plot(*goals[robot], '*', color=colour, markersize=10, markeredgecolor='black',
                  markeredgewidth=0.5)
        trails.append(axes.plot([], [], '-', color=colour, linewidth=1.2)[0])
        if position_std is not None and position_std[robot] > 0.0:
            halos.append(axes.add_patch(Circle(
                positions[0, robot], radii[robot] + UNCERTAINTY_SIGMAS * position_std[robot],
                color=colour, alpha=0.15, linewidth=0)))
        else:
            halos.append(None)
        discs.append(axes.add_patch(Circle(
            positions[0, robot], radii[robot], facecolor=colour,
            edgecolor='dimgrey' if scripted[robot] else 'black',
            hatch='///' if scripted[robot] else None,
            linestyle='--' if scripted[robot] else '-', alpha=0.8, linewidth=0.8)))
        headings.append(axes.plot([], [], '-', color='black', linewidth=1.2)[0]
                        if states.shape[-1] >= 5 else None)
        rings.append(axes.add_patch(Circle(positions[0, robot], radii[robot] * 1.25,
                                           fill=False, linewidth=2.0, visible=False)))
        turn_rings.append(axes.add_patch(Circle(
            positions[0, robot], radii[robot] * TURN_RING, fill=False, linewidth=1.5,
            visible=False)))
    clock = axes.text(0.02, 0.97, '', transform=axes.transAxes, va='top', fontsize=9,
                      family='monospace', bbox={'facecolor': 'white', 'alpha': 0.7,
                                                'linewidth': 0})
    holders = None
    if turns is not None:
        holders = axes.text(0.02, 0.03, '', transform=axes.transAxes, va='bottom', fontsize=6,
                            bbox={'facecolor': 'white', 'alpha': 0.7, 'linewidth': 0})
        if np.any(turns.states):
            turn_legend += turn_handles(rings=True)
        if turn_legend:
            axes.legend(handles=turn_legend, loc='upper right', fontsize=6, framealpha=0.7)
    # Fixed margins rather than a layout engine, which would lay out every frame again.
    figure.subplots_adjust(left=0.12, right=0.97, bottom=0.08, top=0.9)

    def draw(frame):
        step = steps[frame]
        for robot in range(robot_count):
            centre = positions[step, robot]
            discs[robot].set_center(centre)
            if halos[robot] is not None:
                halos[robot].set_center(centre)
            trails[robot].set_data(positions[:step + 1, robot, 0],
                                   positions[:step + 1, robot, 1])
            if headings[robot] is not None:
                yaw = states[step, robot, 4]
                tip = centre + radii[robot] * np.array([math.cos(yaw), math.sin(yaw)])
                headings[robot].set_data([centre[0], tip[0]], [centre[1], tip[1]])
            rings[robot].set_center(centre)
            rings[robot].set_visible(bool(flashing[frame, robot]))
            rings[robot].set_edgecolor(FLASH_COLOURS[frame % 2])
            if turns is not None:
                style = TURN_STYLES.get(int(turns.states[step, robot]))
                turn_rings[robot].set_center(centre)
                turn_rings[robot].set_visible(style is not None)
                if style is not None:
                    turn_rings[robot].set_edgecolor(style[0])
                    turn_rings[robot].set_linestyle(style[1])
        clock.set_text(f't = {times[step]:5.1f} s')
        if holders is not None:
            holders.set_text('\n'.join(
                f"passage {passage}: {', '.join(going) or 'nobody'} "
                f"{'goes' if len(going) < 2 else 'go'}; "
                f"{', '.join(waiting) or 'nobody'} {'waits' if len(waiting) < 2 else 'wait'}"
                for passage, going, waiting in turns.at(step, robot_names)))

    dt = float(times[1] - times[0]) if len(times) > 1 else 1.0
    stride = int(steps[1] - steps[0]) if len(steps) > 1 else 1
    fps = min(MAX_FPS, 1.0 / (dt * stride))
    writer = PillowWriter(fps=fps)
    try:
        with writer.saving(figure, path, DPI):
            for frame in range(len(steps)):
                draw(frame)
                writer.grab_frame()
    finally:
        plt.close(figure)
    return len(steps)


def _set_limits(axes, positions, goals, radii, static_bounds=None):
    """Fit the axes to every position and goal, with a disc's margin, and STATIC_BOUNDS."""
    points = np.vstack([positions.reshape(-1, 2), goals])
    margin = 2.0 * float(np.max(radii)) + 0.2
    low, high = points.min(axis=0) - margin, points.max(axis=0) + margin
    if static_bounds is not None:
        low, high = np.minimum(low, static_bounds[0]), np.maximum(high, static_bounds[1])
    axes.set_xlim(low[0], high[0])
    axes.set_ylim(low[1], high[1])
