"""Right of way at a passage: one order for all, waiting spots, virtual walls (issue 39)."""

import dataclasses
import itertools

import numpy as np
import pytest

from prvo_planner.maps import OCCUPIED, GridMap
from prvo_planner.narrows import find_passages
from prvo_planner.right_of_way import (
    AIM_ALONG,
    FOLLOW_GAP,
    IDLE_INSIDE,
    IDLE_MOVE,
    QUEUE_TIE,
    TIE,
    IdleWatch,
    PassageMap,
    PassageUse,
    QueueWatch,
    conflict,
    goes_first,
    waiting_at,
    with_wall,
)

RESOLUTION = 0.05
RADIUS = 0.25
MARGIN = 0.3


def _door_map():
    """Two rooms 6 x 4 m, a wall 0.1 m thick at x = 3 with a 1.2 m door about y = 2."""
    occupied = np.zeros((80, 120), dtype=bool)
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    occupied[:, 59:61] = True
    occupied[28:52, 59:61] = False
    grid = GridMap(np.where(occupied, OCCUPIED, 0).astype(np.int8), RESOLUTION, (0.0, 0.0))
    return PassageMap(grid, find_passages(grid, RADIUS, MARGIN), RADIUS)


@pytest.fixture(scope='module')
def door():
    return _door_map()


def _use(name, entry, exit_end, distance):
    return PassageUse(name, 0, entry, exit_end, distance)


def test_the_door_is_one_passage_with_an_end_in_each_room(door):
    (passage,) = door.passages
    assert [end.entrance[0] < 3.0 for end in passage.ends] == [True, False]
    assert door.passage_at([[3.0, 2.0], [1.0, 2.0], [5.0, 2.0]]).tolist() == [0, -1, -1]


def test_a_route_through_the_door_comes_in_by_its_side_and_leaves_by_the_other(door):
    east = door.use_of('a', np.array([1.0, 2.0]), np.array([[1.0, 2.0], [5.0, 2.0]]))
    west = door.use_of('b', np.array([5.0, 1.5]), np.array([[5.0, 1.5], [1.0, 2.5]]))
    assert (east.entry, east.exit) == (0, 1) and (west.entry, west.exit) == (1, 0)
    # The way to the passage: to where its cells begin, before the wall.
    start = np.array([1.0, 2.0])
    assert east.distance < 2.0
    assert door.passage_at([start + [east.distance + 0.01, 0.0],
                            start + [east.distance - 0.03, 0.0]]).tolist() == [0, -1]
    assert conflict(east, west) and conflict(west, east)
    inside = door.use_of('c', np.array([3.0, 2.0]), np.array([[3.0, 2.0], [5.0, 2.0]]))
    assert inside.inside and inside.exit == 1 and inside.distance > 0.0


def test_a_route_that_does_not_pass_or_passes_beyond_the_look_ahead_uses_nothing(door):
    assert door.use_of('a', np.array([1.0, 1.0]), np.array([[1.0, 1.0], [1.0, 3.0]])) is None
    far = np.array([[0.2, 2.0], [0.2, 3.8], [0.25, 0.2], [0.3, 3.8], [5.0, 2.0]])
    assert door.use_of('a', far[0], far) is None


def test_a_route_that_only_grazes_a_mouth_uses_nothing(door):
    # Past the door's east mouth, in and out of the passage's cells there by one end.
    route = np.array([[4.4, 2.6], [3.9, 2.2], [4.4, 1.5], [5.5, 1.2]])
    assert door.passage_at(route).tolist() == [-1, 0, -1, -1]
    assert door.use_of('a', route[0], route) is None


def test_a_route_along_the_rim_that_steps_out_and_back_in_has_not_left(door):
    # In by the west, out and back in within a cell's width of the rim, then east.
    (passage,) = door.passages
    west, east = (end.entrance for end in passage.ends)
    wiggle = np.array([[1.5, 2.0], west + [0.05, 0.0], west + [-0.2, 0.0],
                       west + [0.1, 0.0], east + [1.5, 0.0]])
    use = door.use_of('a', wiggle[0], wiggle)
    assert (use.entry, use.exit) == (0, 1)


def test_inside_holds_and_the_shorter_way_goes_first():
    inside = PassageUse('z', 0, None, 1, 1.0)
    coming = _use('a', 1, 0, 0.1)
    assert goes_first(inside, [coming]) and not goes_first(coming, [inside])
    near, far = _use('b', 0, 1, 1.0), _use('a', 1, 0, 1.0 + 2.0 * TIE)
    assert goes_first(near, [far]) and not goes_first(far, [near])
    # Within the tie the smaller name goes first, whoever is a little nearer.
    first, second = _use('a', 0, 1, 1.0 + 0.5 * TIE), _use('b', 1, 0, 1.0)
    assert goes_first(first, [second]) and not goes_first(second, [first])


def test_of_two_inside_that_meet_the_one_with_less_left_goes_on():
    nearly_out, just_in = PassageUse('b', 0, None, 1, 0.3), PassageUse('a', 0, None, 0, 1.2)
    assert goes_first(nearly_out, [just_in]) and not goes_first(just_in, [nearly_out])


def test_robots_going_the_same_way_follow_one_another_in_a_gap_apart():
    inside = PassageUse('z', 0, None, 1, 0.5, np.array([3.5, 2.0]))
    leader = PassageUse('b', 0, 0, 1, 0.4, np.array([2.0, 2.0]))
    assert not conflict(inside, leader) and goes_first(leader, [inside])
    # A follower abreast of the leader holds its place; one a gap behind follows it in.
    for behind, goes in ((0.3, False), (FOLLOW_GAP - 0.05, False), (FOLLOW_GAP + 0.05, True)):
        follower = PassageUse('c', 0, 0, 1, 0.4 + behind, np.array([2.0 - behind, 2.0]))
        assert goes_first(follower, [inside, leader]) is goes, behind
    # Behind one inside, too.
    close = PassageUse('a', 0, 0, 1, 0.2, np.array([3.0, 2.0]))
    assert not goes_first(close, [inside])


def test_a_robot_knows_who_waits_at_its_passage():
    # A held robot would step aside for these (give_way): for one that stands behind it by the
    # order, or behind others, all would wait for good.
    leader = PassageUse('b', 0, 0, 1, 0.4, np.array([2.0, 2.0]))
    follower = PassageUse('c', 0, 0, 1, 0.9, np.array([1.5, 2.0]))
    opposite = PassageUse('a', 0, 1, 0, 2.0, np.array([5.0, 2.0]))
    elsewhere = PassageUse('d', 1, 1, 0, 0.1, np.array([9.0, 2.0]))
    assert waiting_at(leader, [opposite, elsewhere]) == ('a',)
    assert waiting_at(leader, [follower, opposite, elsewhere]) == ('c', 'a')
    # The follower sees the leader go and the one coming the other way wait.
    assert waiting_at(follower, [leader, opposite, elsewhere]) == ('a',)
    # Behind the leader a gap back, the follower goes too.
    spaced = PassageUse('c', 0, 0, 1, 0.4 + FOLLOW_GAP + 0.1,
                        np.array([2.0 - FOLLOW_GAP - 0.1, 2.0]))
    assert waiting_at(leader, [spaced]) == ()
    # One inside coming out holds the door: it goes, the follower waits.
    inside = PassageUse('z', 0, None, 0, 0.5, np.array([3.0, 2.0]))
    assert waiting_at(leader, [follower, inside]) == ('c',)


def test_inside_a_robot_follows_the_centre_line_beyond_its_way_out_until_it_is_out(door):
    (passage,) = door.passages
    way_in, way_out = passage.ends
    use = PassageUse('a', 0, None, 1, 1.0)
    before = way_out.entrance - 0.2 * way_out.outward
    assert door.passage_at([before])[0] == 0
    # The centre line runs on straight out of the way out, AIM_ALONG ahead of the robot.
    aim = door.aim(use, before)
    assert np.allclose(aim, way_out.entrance + way_out.outward * (AIM_ALONG - 0.2), atol=0.03)
    # Out past the entrance, still among the passage's cells: its route leads it on.
    beyond = way_out.entrance + 0.1 * way_out.outward
    assert door.passage_at([beyond])[0] == 0
    assert door.aim(use, beyond) is None


def test_inside_off_the_middle_a_robot_heads_back_to_it_before_the_jambs(door):
    # Just in by the west, 0.3 m off the middle (y = 2) of a door in the wall at x = 2.95-3.05:
    # it aims at the middle AIM_ALONG on, short of the wall, not at the way out past the jamb.
    (passage,) = door.passages
    way_in, way_out = passage.ends
    off = way_in.entrance + np.array([0.2, -0.3])
    assert door.passage_at([off])[0] == 0
    for use in (PassageUse('a', 0, None, 1, 1.0), PassageUse('a', 0, None, 0, 1.0)):
        end = passage.ends[use.exit]
        aim = door.aim(use, off)
        assert abs(aim[1] - 2.0) < 0.05
        assert abs(aim[0] - off[0]) == pytest.approx(AIM_ALONG, abs=0.05)
        assert np.dot(aim - off, end.entrance - off) > 0.0


def test_a_waiting_robot_names_the_end_it_waits_at_and_whether_a_spot_fits_there(door):
    (passage,) = door.passages
    inside = PassageUse('z', 0, None, 0, 0.5, np.array([3.0, 2.0]))
    me = PassageUse('a', 0, 0, 1, 1.0, np.array([1.5, 2.0]))
    decision = door.decision(me, [inside], me.position)
    np.testing.assert_array_equal(decision.entrance, passage.ends[0].entrance)
    assert not decision.without_spot
    spotless = PassageMap.__new__(PassageMap)
    spotless.__dict__.update(door.__dict__)
    spotless.passages = (dataclasses.replace(passage, ends=(
        dataclasses.replace(passage.ends[0], waiting_spot=None), passage.ends[1])),)
    decision = spotless.decision(me, [inside], me.position)
    assert decision.without_spot and decision.waiting_spot is None
    # Going, or held behind one going its way, it waits at no end.
    assert door.decision(inside, [me], inside.position).entrance is None
    leader = PassageUse('b', 0, 0, 1, 0.4, np.array([2.0, 2.0]))
    follower = PassageUse('c', 0, 0, 1, 0.8, np.array([1.6, 2.0]))
    assert not door.decision(follower, [leader], follower.position).without_spot


def test_a_robot_held_behind_a_leader_stands_without_a_spot_or_a_wall(door):
    leader = PassageUse('b', 0, 0, 1, 0.4, np.array([2.0, 2.0]))
    follower = PassageUse('c', 0, 0, 1, 0.8, np.array([1.6, 2.0]))
    decision = door.decision(follower, [leader], follower.position)
    assert not decision.goes and decision.waiting_spot is None and decision.wall is None


def test_at_two_ends_robots_conflict_when_head_on_at_more_when_their_ways_out_differ():
    # Two ends: head-on is one coming in by the end the other leaves by, or both inside and
    # leaving by different ends; every pair of uses.
    uses = ([PassageUse('out', 0, entry, exit_end, 1.0)
             for entry in (0, 1) for exit_end in (1 - entry, None)]
            + [PassageUse('in', 0, None, exit_end, 1.0) for exit_end in (0, 1, None)])
    for first, second in itertools.product(uses, repeat=2):
        head_on = (first.exit != second.exit if first.inside and second.inside else
                   (first.entry is not None and first.entry == second.exit)
                   or (second.entry is not None and second.entry == first.exit))
        assert conflict(first, second) == head_on, (first, second)
    # Three ends (pillars12's gaps): ways out by different ends cross once both are in, also
    # for two that come in by the same end or one outside and one inside; the same way out
    # never conflicts. Else a robot let in by one rule is sent back out by the other.
    assert conflict(PassageUse('a', 0, 0, 1, 1.0), PassageUse('b', 0, 0, 2, 1.5))
    assert conflict(PassageUse('a', 0, 1, 2, 1.0), PassageUse('b', 0, None, 0, 2.0))
    assert not conflict(PassageUse('a', 0, 0, 2, 1.0), PassageUse('b', 0, 1, 2, 1.0))
    assert not conflict(PassageUse('a', 0, 1, 2, 1.0), PassageUse('b', 0, None, 2, 2.0))


@pytest.mark.parametrize('ends, with_came', [(2, False), (3, True)])
def test_every_robot_computing_the_order_finds_no_two_that_meet_both_going(ends, with_came):
    # The property that makes the rule safe to decide apart: from the same uses, of any two
    # that would meet head-on, at most one goes; and someone goes. Also with when each came
    # (first come, first served), at a passage of three ends.
    generator = np.random.default_rng(39)
    for _ in range(300):
        uses = []
        for index in range(int(generator.integers(2, 7))):
            inside = generator.random() < 0.25
            entry = None if inside else int(generator.integers(0, ends))
            exit_end = (int(generator.integers(0, ends)) if inside
                        else (entry + int(generator.integers(1, ends))) % ends)
            came = float(generator.uniform(0.0, 8.0)) if with_came and not inside else None
            uses.append(PassageUse(f'robot_{index}', 0, entry, exit_end,
                                   float(generator.uniform(0.0, 4.0)),
                                   generator.uniform(0.0, 3.0, size=2), came))
        going = [goes_first(use, [other for other in uses if other is not use])
                 for use in uses]
        assert any(going), uses
        for (first, goes_a), (second, goes_b) in itertools.combinations(
                zip(uses, going, strict=True), 2):
            assert not (conflict(first, second) and goes_a and goes_b), (first, second)


def test_a_robot_without_the_right_of_way_waits_beside_its_entrance_behind_a_wall(door):
    (passage,) = door.passages
    inside = PassageUse('z', 0, None, 1, 0.5)
    position = np.array([4.6, 2.1])
    me = door.use_of('a', position, np.array([position, [1.0, 2.0]]))
    decision = door.decision(me, [inside], position)
    assert not decision.goes
    end = passage.ends[me.entry]
    np.testing.assert_array_equal(decision.waiting_spot, end.waiting_spot)
    # The wall lies across the way in, a radius outside the passage's mouth, and the robot is
    # on its open side.
    wall = decision.wall
    along = wall[1] - wall[0]
    assert abs(np.dot(along, end.outward)) < 1e-9
    assert np.dot(wall.mean(axis=0) - end.entrance, end.outward) == pytest.approx(RADIUS)
    assert np.linalg.norm(along) >= passage.width
    assert np.dot(position - wall[0], end.outward) > RADIUS
    obstacles = with_wall(None, wall)
    np.testing.assert_array_equal(obstacles.segments[-1], wall)


def test_first_come_first_served_and_those_that_came_together_by_their_ways(door):
    # 'a' came to the west end and waits at its spot; 'b' comes to the east end later, nearer
    # its entrance than the spot's way to the west one. By the ways alone 'b' would go first,
    # and so would every robot that came after it while 'a' waited.
    (passage,) = door.passages
    west, east = passage.ends
    spot = west.waiting_spot
    waiting = door.use_of('a', spot, np.array([spot, west.entrance, east.entrance + [1.5, 0.0]]))
    b_position = east.entrance + [1.0, 0.0]
    coming = door.use_of('b', b_position, np.array([b_position, [1.0, 2.0]]))
    assert (waiting.entry, coming.entry) == (0, 1) and conflict(waiting, coming)
    assert waiting.distance > coming.distance + TIE
    assert goes_first(coming, [waiting]) and not goes_first(waiting, [coming])
    watch = QueueWatch()
    (waiting_seen,) = watch.ordered([waiting], 1.0)
    for stamp, first_goes in ((1.0 + QUEUE_TIE, False), (1.0 + QUEUE_TIE + 0.1, True)):
        waiting_seen, coming_seen = watch.ordered([waiting, coming], stamp)
        assert (waiting_seen.came, coming_seen.came) == (1.0, stamp)
        assert goes_first(waiting_seen, [coming_seen]) is first_goes
        assert goes_first(coming_seen, [waiting_seen]) is not first_goes
        watch = QueueWatch()
        watch.ordered([waiting], 1.0)
    # It keeps its place while it uses the passage, inside (backing out) or by another end;
    # once it uses none, it comes anew.
    inside = PassageUse('a', 0, None, 1, 0.5)
    assert watch.ordered([inside], 9.0) == [inside]
    (back,) = watch.ordered([dataclasses.replace(waiting, entry=1)], 9.5)
    assert back.came == 1.0
    assert watch.ordered([], 10.0) == []
    (later,) = watch.ordered([waiting], 10.5)
    assert later.came == 10.5


def test_a_robot_at_the_mouth_gets_no_wall_it_would_start_inside(door):
    (passage,) = door.passages
    end = passage.ends[1]
    position = end.entrance + end.outward * RADIUS
    me = PassageUse('a', 0, 1, 0, 0.3)
    decision = door.decision(me, [PassageUse('z', 0, None, 1, 0.5)], position)
    assert not decision.goes and decision.wall is None


def test_a_neighbour_standing_in_a_passage_stops_claiming_it_after_the_timeout():
    watch = IdleWatch()
    standing = PassageUse('broken', 0, None, 1, 0.6, np.array([3.0, 2.0]))
    passing = PassageUse('passing', 0, None, 1, 0.6, np.array([2.5, 2.0]))
    coming = PassageUse('coming', 0, 1, 0, 2.0, np.array([5.0, 2.0]))
    for step in range(int(IDLE_INSIDE / 0.1) + 11):
        stamp = 0.1 * step
        moved = dataclasses.replace(passing, position=passing.position + [0.06 * step, 0.0])
        kept = watch.claiming([standing, moved, coming], stamp)
        names = [use.name for use in kept]
        assert ('broken' in names) is (stamp <= IDLE_INSIDE + 1e-9), stamp
        assert 'passing' in names and 'coming' in names
    # The one coming the other way now goes, the broken-down robot no longer holding the door.
    assert not goes_first(coming, [standing])
    assert goes_first(coming, [use for use in kept if use.name != 'passing'])
    # Once it moves again it claims the passage anew.
    moved_on = dataclasses.replace(standing, position=standing.position + [IDLE_MOVE + 0.1, 0.0])
    assert 'broken' in [use.name for use in watch.claiming([moved_on], stamp + 0.1)]
