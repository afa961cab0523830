"""What neighbours announce, kept with its stamps: held values against taking them anew."""

import copy

import numpy as np

from prvo_planner.announced import AnnouncedValues, HeldValues, held

STAMPS = np.round(np.arange(0.0, 2.0, 0.1), 1)


def random_values(rng, count):
    """Return AnnouncedValues with COUNT announcements at random stamps of STAMPS."""
    announced = AnnouncedValues()
    for value in range(count):
        announced.add(float(rng.choice(STAMPS)), value)
    return announced


def test_a_held_value_is_what_take_returns_for_every_stamp_it_holds_for():
    rng = np.random.default_rng(5)
    for _ in range(300):
        announced = random_values(rng, int(rng.integers(0, 6)))
        stamp = float(rng.choice(STAMPS) + rng.choice([0.0, 0.05]))
        value, after, until = announced.held(stamp)
        for other in STAMPS + 0.05 * rng.integers(0, 2, STAMPS.size):
            fresh = copy.deepcopy(announced)
            kept = list(fresh._announced)
            if after < other <= until:
                # The same value, and nothing more dropped.
                assert fresh.take(other) == value and fresh._announced == kept
            elif other > until:
                assert announced.value_at(other) != value or value is None


def test_nothing_announced_holds_for_every_stamp():
    assert held(None, 3.0) == (None, -np.inf, np.inf)
    assert AnnouncedValues().held(3.0) == (None, -np.inf, np.inf)
    # From the start, until the next value's stamp; a value announced ahead holds after it.
    announced = AnnouncedValues()
    announced.add(0.0, 'a')
    announced.add(0.5, 'b')
    assert announced.held(0.3) == ('a', -np.inf, 0.5)
    assert announced.held(0.6) == ('b', 0.5, np.inf)
    ahead = AnnouncedValues()
    ahead.add(0.5, 'c')
    assert ahead.held(0.3) == (None, -np.inf, 0.5)


def test_held_values_are_the_values_taken_anew_at_every_plan():
    # A team's announcements over a run: robots announce now and ahead, restate from the start,
    # leave and come back, while the plans' stamps go on (and once go back, as after a
    # restart). Every plan's held values are those taken anew from a twin of every record.
    rng = np.random.default_rng(40)
    robots = [f'robot_{index}' for index in range(6)]
    records = [{}, {}]
    twins = [{}, {}]
    values = HeldValues(2)

    def take(robot, stamp):
        pairs = [held(record.get(robot), stamp) for record in records]
        return (tuple(pair[0] for pair in pairs), max(pair[1] for pair in pairs),
                min(pair[2] for pair in pairs))

    stamp = 0.0
    names = tuple(robots)
    for step in range(400):
        stamp = round(stamp + 0.1, 1) if step != 250 else 1.0
        for _ in range(int(rng.integers(0, 3))):
            robot, quantity = str(rng.choice(robots)), int(rng.integers(2))
            announced_at = float(rng.choice([0.0, stamp - 0.1, stamp, stamp + 0.2]))
            value = float(rng.random())
            for record in (records[quantity], twins[quantity]):
                record.setdefault(robot, AnnouncedValues()).add(max(announced_at, 0.0), value)
            values.changed(robot)
        if rng.random() < 0.03:
            robot = str(rng.choice(robots))
            for record in (*records, *twins):
                record.pop(robot, None)
            values.changed(robot)
        if rng.random() < 0.05:
            names = tuple(robot for robot in robots if rng.random() < 0.8)
        expected = tuple(tuple(None if robot not in twin else twin[robot].take(stamp)
                               for robot in names) for twin in twins)
        assert values.values(names, stamp, take) == expected, step
