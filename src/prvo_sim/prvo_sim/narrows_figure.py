"""Pictures of the one-way passages a planner finds on a scenario's map (`prvo_planner.narrows`).

    python -m prvo_sim.narrows_figure [--scenarios doorway8 office] [--margin 0.25]
                                      [--folder docs/images]

For each scenario, the grid a planner reads (its static world rasterised, `StaticWorld.grid`),
the passages found for its largest robot radius and MARGIN, and writes
FOLDER/narrows_<scenario>.png: occupied cells dark, each passage's cells shaded, its centre
lines, its entrances (dots, with an arrow out) and its waiting spots (a robot's disc). Prints
one line per passage. Exit codes: 0 written, 2 bad input.
"""

import argparse
import pathlib
import sys

from matplotlib.patches import Circle
import numpy as np

from prvo_planner.maps import occupied_cells
from prvo_planner.narrows import find_passages, passing_width
from prvo_sim.plotting import plt
from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario

# Each robot keeps this beside its lane in the pictures [m]: half a diameter of the shipped
# robots (radius 0.25), so that two of them pass where 1.5 m is free.
MARGIN = 0.25
_PASSAGE_COLOUR = '#e69f00'
_SPOT_COLOUR = '#0072b2'


def draw_passages(axes, grid, passages, radius):
    """Draw GRID's occupied cells and PASSAGES (their cells, lines, ends, spots of RADIUS)."""
    height, width = grid.shape
    extent = (grid.origin[0], grid.origin[0] + width * grid.resolution,
              grid.origin[1], grid.origin[1] + height * grid.resolution)
    shown = np.ones((height, width, 3))
    shown[occupied_cells(grid)] = (0.33, 0.33, 0.38)
    for passage in passages:
        shown[passage.cells[:, 0], passage.cells[:, 1]] = (0.98, 0.85, 0.6)
    axes.imshow(shown, origin='lower', extent=extent, interpolation='nearest')
    for passage in passages:
        for line in passage.centre_lines:
            axes.plot(line[:, 0], line[:, 1], '-', color=_PASSAGE_COLOUR, linewidth=1.5)
        for end in passage.ends:
            axes.plot(*end.entrance, 'o', color=_PASSAGE_COLOUR, markersize=4)
            axes.annotate('', xy=end.entrance + 0.5 * end.outward, xytext=end.entrance,
                          arrowprops={'arrowstyle': '->', 'color': _PASSAGE_COLOUR})
            if end.waiting_spot is not None:
                axes.add_patch(Circle(end.waiting_spot, radius, fill=False, color=_SPOT_COLOUR,
                                      linewidth=1.2))
                axes.plot(*end.waiting_spot, '.', color=_SPOT_COLOUR)
        middle = passage.centre_lines[0][len(passage.centre_lines[0]) // 2]
        axes.annotate(f'{passage.width:.2f} m', middle, xytext=(6, 6),
                      textcoords='offset points', fontsize=7, color='black')
    axes.set_aspect('equal')
    axes.set_xlabel('x [m]')
    axes.set_ylabel('y [m]')


def write_picture(path, scenario, margin):
    """Write the picture of SCENARIO's passages for MARGIN [m] to PATH; return the passages."""
    grid = scenario.static_world.grid
    radius = max(robot.radius for robot in scenario.robots)
    passages = find_passages(grid, radius, margin)
    size = np.array(grid.shape[::-1]) * grid.resolution
    # The longer side 8 inches, the title's line on top.
    figure, axes = plt.subplots(figsize=tuple(size * 8.0 / size.max() + (0.0, 0.6)))
    draw_passages(axes, grid, passages, radius)
    axes.set_title(f'{scenario.name}: {len(passages)} passage(s) narrower than '
                   f'{passing_width(radius, margin):.2f} m (radius {radius:g} m, margin '
                   f'{margin:g} m); waiting spots in blue', fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return passages


def main(argv=None):
    """Write the pictures; print each passage; return the exit code."""
    parser = argparse.ArgumentParser(prog='python -m prvo_sim.narrows_figure',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('--scenarios', nargs='+', default=['doorway8', 'office'])
    parser.add_argument('--margin', type=float, default=MARGIN)
    parser.add_argument('--folder', type=pathlib.Path, default=pathlib.Path('docs/images'))
    try:
        options = parser.parse_args(argv)
        scenarios = [load_scenario(find_scenario(name)) for name in options.scenarios]
    except SystemExit as exit_:
        return 2 if exit_.code else 0
    except ScenarioError as error:
        print(error, file=sys.stderr)
        return 2
    if not options.margin >= 0.0:
        print(f'--margin must be at least 0, got {options.margin}', file=sys.stderr)
        return 2
    for scenario in scenarios:
        if scenario.static_world.grid is None:
            print(f'{scenario.name}: no walls or map, no passages', file=sys.stderr)
            return 2
        path = options.folder / f'narrows_{scenario.name}.png'
        for passage in write_picture(path, scenario, options.margin):
            ends = ', '.join(f'({x:.2f}, {y:.2f})' for x, y in
                             (end.entrance for end in passage.ends))
            print(f'{scenario.name}: width {passage.width:.2f} m, length '
                  f'{passage.length:.2f} m, ends {ends}')
        print(f'wrote {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
