"""What neighbours announce, with the stamps it holds for, read by a plan without ROS.

A neighbour announces its size, its share of the avoidance and its route, each stamped: a value
holds for the plans of stamps after its own (`AnnouncedValues`). A plan reads what holds of
every neighbour; what holds changes only when a neighbour announces, or when the plans' stamps
pass a value announced ahead. `HeldValues` keeps what held for the last plan with the stamps it
holds for, so that a plan takes anew only the neighbours whose values changed, found in one
array comparison, instead of reading every announcement of every neighbour.
"""

import math

import numpy as np

# An announcement stamped s > 0 holds for the plans of stamps after s; one stamped 0, from the
# start (a robot's announcements before its first plan, the simulator's of scripted robots).
ANNOUNCED_FROM_THE_START = 0.0
# Announcements kept per neighbour and quantity: the plans to come use the newest before their
# stamp and the later ones, of which a neighbour in lockstep has at most one or two; the bound
# holds against a neighbour flooding changes faster than this robot plans.
MAX_KEPT_ANNOUNCEMENTS = 16


class AnnouncedValues:
    """What one neighbour announced of one quantity (radius or share), each with its stamp.

    `value_at(stamp)` is what holds for the plan of STAMP: the newest value announced with a
    stamp before it, or from the start (ANNOUNCED_FROM_THE_START). An announcement replaces
    those stamped at or after its own stamp (the neighbour restated them: it restarted, or its
    clock went back); one from the start replaces all. `take(stamp)` also drops what no plan of
    STAMP or later can use; at most MAX_KEPT_ANNOUNCEMENTS are kept, the oldest going first.
    """

    def __init__(self):
        # (stamp, value), stamps increasing.
        self._announced = []

    def __len__(self):
        return len(self._announced)

    def add(self, stamp, value):
        """Take VALUE, announced with STAMP [s] (finite, >= 0)."""
        kept = [announced for announced in self._announced if announced[0] < stamp]
        kept.append((stamp, value))
        self._announced = kept[-MAX_KEPT_ANNOUNCEMENTS:]

    def value_at(self, stamp):
        """Return the value that holds for the plan of STAMP, None if none announced does."""
        index = self._index_at(stamp)
        return None if index is None else self._announced[index][1]

    def take(self, stamp):
        """Return `value_at(STAMP)`, dropping what no plan of STAMP or later can use.

        That is every value announced before the one that holds at STAMP.
        """
        index = self._index_at(stamp)
        if index is None:
            return None
        del self._announced[:index]
        return self._announced[0][1]

    def held(self, stamp):
        """Return (`take(STAMP)`, after, until): `take` of any stamp in (after, until] alike.

        For those stamps `take` returns the same value and drops nothing more: the value taken
        holds from its stamp (from the start: from -inf) to the next one's (none: to inf);
        None holds up to the first value's stamp.
        """
        value = self.take(stamp)
        announced = self._announced
        if value is None:
            return None, -math.inf, announced[0][0] if announced else math.inf
        first = announced[0][0]
        return (value, -math.inf if first == ANNOUNCED_FROM_THE_START else first,
                announced[1][0] if len(announced) > 1 else math.inf)

    def _index_at(self, stamp):
        for index in range(len(self._announced) - 1, -1, -1):
            announced_stamp = self._announced[index][0]
            if announced_stamp < stamp or announced_stamp == ANNOUNCED_FROM_THE_START:
                return index
        return None


def held(announced, stamp):
    """Return `AnnouncedValues.held(STAMP)` of ANNOUNCED; None: nothing, for every stamp."""
    return (None, -math.inf, math.inf) if announced is None else announced.held(stamp)


class HeldValues:
    """Per neighbour of a robot, the values that held for its last plan, and for which stamps.

    `values(names, stamp, take)` returns the values of the plan of STAMP, one tuple per
    quantity in the order of NAMES. TAKE(robot, stamp) returns (the robot's values, one per
    quantity; after; until): what holds for the plans of every stamp in (after, until], as
    `AnnouncedValues.held` says of each. A neighbour's values are taken anew when STAMP is
    out of those, after `changed(robot)` (it announced, or what it announced was dropped or read
    elsewhere), and for every neighbour after `clear()` or when NAMES change.
    """

    def __init__(self, quantities):
        self._quantities = quantities
        self.clear()

    def clear(self):
        """Take every neighbour's values anew at the next plan."""
        self._names = None

    def changed(self, robot):
        """Take ROBOT's values anew at the next plan."""
        index = self._index.get(robot) if self._names is not None else None
        if index is not None:
            self._after[index] = math.inf

    def values(self, names, stamp, take):
        """Return the values of the plan of STAMP, a tuple per quantity in the order of NAMES."""
        if names != self._names:
            self._names, self._index = names, {robot: index for index, robot in enumerate(names)}
            self._columns = [[None] * len(names) for _ in range(self._quantities)]
            self._after, self._until = np.full(len(names), math.inf), np.zeros(len(names))
        for index in np.flatnonzero(~((self._after < stamp) & (stamp <= self._until))).tolist():
            values, self._after[index], self._until[index] = take(names[index], stamp)
            for column, value in zip(self._columns, values, strict=True):
                column[index] = value
        return tuple(tuple(column) for column in self._columns)
