"""
Detours: a robot kept waiting at a passage takes a way round it once waiting has cost as much.

The right of way (`prvo_planner.right_of_way`) makes a robot wait its turn at a passage. Where
the map has another way to the goal that avoids the passage (pillars, a second door), waiting is
a bet on how long the turn will take, which the robot cannot know: it depends on who comes
after. The rule is the ski-rental one: the robot waits until the time it has waited equals the
time the way round would add at full speed (its extra length over the robot's speed), then
takes the way round. Whatever the wait would have been, the robot then arrives at most about
twice as late as the better of the two choices would have made it; where the way round is
barely longer it goes round at once, and where there is none (a single door) it waits as
before.

A robot that took a way round keeps avoiding that passage until its goal or map changes:
turning back when the passage clears would make its route flip, and its neighbours could not
rely on it (`routes.RouteFlips`). A way round may meet another passage, at which the same rule
holds, avoiding both. Only waiting at an end for the turn counts: a robot holding its place
behind one going its way, or inside, follows. ROS-free: the planner node and the in-process
engine run the same.
"""

import numpy as np

from prvo_planner.route import path_length


class DetourWatch:
    """
    How long a robot has waited at a passage, and the ways round the passages it avoids.

    The ways round are searched once per goal and set of passages avoided (`way_round`: a
    `RouteMap` search, tens of milliseconds on a map of 200 x 200 cells, a third of a second on
    a 50 m office; each kept holds 4 bytes a cell), in `update` itself or, where it must not
    wait for one (a node's callback), elsewhere: `update(..., search=False)` then names the one
    it lacks in `wanted`, and `install` takes it. `reset` forgets them (a new goal or map).
    """

    def __init__(self):
        self.reset()

    def reset(self):
        """Forget the waiting, the passages avoided and the ways round."""
        # (passage, when the robot began to wait at it) while it waits at an end, else None.
        self._waiting = None
        # Indices of the passages the robot goes round.
        self.avoided = frozenset()
        # Ways round searched: avoided set -> route tree (None: no way reaches the goal).
        self._trees = {}
        # The avoided set whose way round an update lacked (search=False), None: none.
        self.wanted = None

    def install(self, avoided, tree):
        """Take TREE, the way round the passages AVOIDED (`way_round`) searched elsewhere."""
        self._trees[avoided] = tree
        if self.wanted == avoided:
            self.wanted = None

    def update(self, stamp, decision, position, remaining, speed, route_map, passage_map, goal,
               search=True):
        """
        Return the route tree to follow from now on round the passage it waits at, None: stay.

        Parameters
        ----------
        stamp : float
            The plan's time [s].
        decision : right_of_way.Decision or None
            The robot's right of way at the passage on its route.
        position : numpy.ndarray
            Shape (2,): where the robot is [m].
        remaining : float
            The length of its route to the goal [m], through the passage.
        speed : float
            Its top speed [m/s], > 0.
        route_map : route.RouteMap
            The map's route graph.
        passage_map : right_of_way.PassageMap
            The map's passages, which DECISION's passage indexes.
        goal : numpy.ndarray
            Shape (2,): the goal [m].
        search : bool
            Search a way round not searched yet here; False: name it in `wanted` and wait
            for it (`install`).

        """
        if (decision is None or decision.goes or decision.use.inside
                or decision.entrance is None):
            self._waiting = None
            return None
        passage = decision.use.passage
        if self._waiting is None or self._waiting[0] != passage:
            self._waiting = (passage, stamp)
        avoided = self.avoided | {passage}
        if avoided not in self._trees:
            if not search:
                self.wanted = avoided
                return None
            self._trees[avoided] = way_round(avoided, route_map, passage_map, goal)
        tree = self._trees[avoided]
        if tree is None:
            return None
        way = tree.route_from(position)
        if way is None:
            return None
        extra = path_length(way) + float(np.hypot(*(way[0] - position))) - remaining
        if (stamp - self._waiting[1]) * speed < extra:
            return None
        self.avoided, self._waiting = avoided, None
        return tree


def way_round(avoided, route_map, passage_map, goal):
    """
    Return the route tree to GOAL round the passages AVOIDED, None where no way reaches it.

    AVOIDED: indices into PASSAGE_MAP's passages (`right_of_way.PassageMap`); ROUTE_MAP: the
    map's `route.RouteMap`; GOAL (2,) [m]. None too where the goal lies in one of them.
    """
    if int(passage_map.passage_at(goal[None])[0]) in avoided:
        return None
    closed = [passage_map.passages[index].cells for index in sorted(avoided)]
    tree = route_map.without(np.concatenate(closed)).tree_to(goal)
    return tree if tree.goal_cell is not None else None
