"""Who holds each passage and who waits for it, step by step: the right of way of a run.

Each planner decides at every step whether it goes through the passage on its route or waits
(`prvo_planner.right_of_way.Decision`). The in-process engine records that decision per robot
as one of NONE (no passage on its route, or the rule off), GOES (it holds the passage: inside
it, or let in) and WAITS, with the passage it concerns; the plot and the GIF draw it. A ROS
run has no record of it (the decisions stay in the planner processes, which report them on
/diagnostics): its pictures show no turns.
"""

from dataclasses import dataclass

import numpy as np

NONE, GOES, WAITS = 0, 1, 2
# A robot's passage where it has none.
NO_PASSAGE = -1


@dataclass(frozen=True)
class PassageShape:
    """
    Where a passage lies in the world, for drawing it.

    Attributes
    ----------
    passage : prvo_planner.narrows.Passage
        The passage; its `cells` index the grid of ORIGIN and RESOLUTION.
    origin : numpy.ndarray
        Shape (2,): the world position [m] of the grid's cell (0, 0)'s lower left corner.
    resolution : float
        The grid's cell side [m].

    """

    passage: object
    origin: np.ndarray
    resolution: float

    def mask(self):
        """Return (mask (H, W) bool over the passage's box, extent (x0, x1, y0, y1) [m]).

        The box has one free cell around the passage, so that an outline drawn of it closes.
        """
        cells = self.passage.cells
        low = cells.min(axis=0) - 1
        mask = np.zeros(tuple(cells.max(axis=0) - low + 2), dtype=bool)
        mask[tuple((cells - low).T)] = True
        x0, y0 = self.origin + self.resolution * low[::-1]
        height, width = mask.shape
        return mask, (x0, x0 + width * self.resolution, y0, y0 + height * self.resolution)


@dataclass(frozen=True)
class Turns:
    """
    The right of way of every robot at every recorded step of a run.

    Attributes
    ----------
    states : numpy.ndarray
        Shape (T, N), int: NONE, GOES or WAITS.
    passages : numpy.ndarray
        Shape (T, N), int: the index in SHAPES of the passage of each state, NO_PASSAGE with
        NONE.
    shapes : tuple of PassageShape
        Every passage a robot went or waited at, in the order first met.

    """

    states: np.ndarray
    passages: np.ndarray
    shapes: tuple

    def at(self, step, names):
        """Return [(passage index, [names that go], [names that wait])] at STEP, by passage.

        NAMES: the robots' names, in the order of the states' columns. Only passages with a
        robot going or waiting are listed.
        """
        states, passages = self.states[step], self.passages[step]
        listed = []
        for passage in range(len(self.shapes)):
            going, waiting = ([names[robot] for robot in np.flatnonzero(
                (passages == passage) & (states == state))] for state in (GOES, WAITS))
            if going or waiting:
                listed.append((passage, going, waiting))
        return listed


class TurnBook:
    """What a team's agents decide at their passages, reduced to states and shared indices.

    Agents find their passages each on their own map (robots of other sizes find others), so
    one passage has an index on each agent's map; the book numbers the distinct passages of
    the run once, by their cells on their grid.
    """

    def __init__(self):
        self.shapes = []
        self._numbers = {}

    def record(self, decisions, passage_maps, grids):
        """Return (states (N,) int, passages (N,) int) of the robots' DECISIONS at a step.

        DECISIONS: per robot, its `right_of_way.Decision` or None; PASSAGE_MAPS: the
        `right_of_way.PassageMap` each decision's index refers to (None with no decision);
        GRIDS: the `maps.GridMap` of each map.
        """
        states = np.full(len(decisions), NONE, dtype=np.int8)
        passages = np.full(len(decisions), NO_PASSAGE)
        for robot, (decision, passage_map, grid) in enumerate(
                zip(decisions, passage_maps, grids, strict=True)):
            if decision is None:
                continue
            states[robot] = GOES if decision.goes else WAITS
            passages[robot] = self._number(passage_map.passages[decision.use.passage], grid)
        return states, passages

    def _number(self, passage, grid):
        """Return the run's index of PASSAGE, found on GRID; a new one is added."""
        origin = np.asarray(grid.origin, dtype=float)
        key = (passage.cells.tobytes(), origin.tobytes(), grid.resolution)
        if key not in self._numbers:
            self._numbers[key] = len(self.shapes)
            self.shapes.append(PassageShape(passage, origin, float(grid.resolution)))
        return self._numbers[key]
