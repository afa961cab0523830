"""Paths read from their serialized bytes: work bounded by their length, a path sent again free."""

import struct

from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.serialization import serialize_message

from prvo_msgs_util import (
    MAX_PATH_POSES,
    MAX_WORLD_COORDINATE,
    PLAN_QOS,
    PLAN_READER_QOS,
    MessageFault,
    SerializedPathReader,
    make_path,
    path_to_waypoints,
    serialized_path_to_waypoints,
    serialized_route,
    subscribe_route,
)
import prvo_msgs_util.conversions as conversions

# Frame names of every length modulo 8 move the positions across every alignment case.
NAMES = ['', 'm', 'map', 'odom', 'w\u00f6rld', 'robot_1/base_link', 'a' * 13, 'b' * 30]


def test_serialized_path_gives_the_waypoints_of_the_message():
    rng = np.random.default_rng(5)
    for count in (0, 1, 2, 9, 64):
        msg = make_path(rng.uniform(0.0, 1e5), rng.uniform(-50.0, 50.0, (count, 2)),
                        NAMES[count % len(NAMES)])
        for index, pose in enumerate(msg.poses):
            pose.header.frame_id = NAMES[(index + count) % len(NAMES)]
            pose.pose.position.z, pose.pose.orientation.z = rng.normal(size=2)
        waypoints = serialized_path_to_waypoints(serialize_message(msg), expected_frame=None)
        assert waypoints.shape == (count, 2)
        np.testing.assert_array_equal(waypoints, path_to_waypoints(msg, expected_frame=None))


def _path(change):
    msg = make_path(1.0, [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]], 'map')
    change(msg)
    return msg


def _set(msg, index, field, value):
    setattr(msg.poses[index].pose.position, field, value)


@pytest.mark.parametrize(('change', 'fault'), [
    (lambda msg: setattr(msg.header, 'frame_id', 'odom'), "header.frame_id is 'odom'"),
    (lambda msg: setattr(msg.poses[2].header, 'frame_id', 'odom'),
     r"poses\[2\].header.frame_id is 'odom'"),
    (lambda msg: _set(msg, 1, 'y', float('nan')), r'poses\[1\].pose.position contains NaN'),
    (lambda msg: _set(msg, 2, 'x', -float('inf')), r'poses\[2\].pose.position contains NaN'),
    (lambda msg: _set(msg, 0, 'x', 2 * MAX_WORLD_COORDINATE), r'poses\[0\].pose.position is '
     'beyond'),
])
def test_path_faults_are_those_of_the_message(change, fault):
    msg = _path(change)
    for convert, argument in ((path_to_waypoints, msg),
                              (serialized_path_to_waypoints, serialize_message(msg))):
        with pytest.raises(MessageFault, match=fault):
            convert(argument)


@pytest.mark.parametrize(('corrupt', 'fault'), [
    (lambda data: data[:-8], 'truncated'),
    (lambda data: data[:20], 'truncated'),
    (lambda data: b'\x00\x07' + data[2:], 'no CDR encapsulation header'),
    (lambda data: data[:12] + struct.pack('<I', 10_000) + data[16:], 'malformed header'),
])
def test_malformed_serialized_path_is_a_named_fault(corrupt, fault):
    with pytest.raises(MessageFault, match=fault):
        serialized_path_to_waypoints(corrupt(serialize_message(_path(lambda msg: None))))


def test_a_path_longer_than_the_bound_is_refused_from_its_length_alone():
    # A header and the length of 100,000 poses, without the poses: refused before reading one
    # (reading them would find the message truncated). Deserialized, they took 5 s.
    empty = serialize_message(make_path(1.0, [], 'map'))
    claimed = empty[:-4] + struct.pack('<I', 100_000)
    with pytest.raises(MessageFault, match=f'the path has 100000 poses, more than '
                       f'{MAX_PATH_POSES}'):
        serialized_path_to_waypoints(claimed)
    longest = make_path(1.0, np.zeros((MAX_PATH_POSES, 2)), 'map')
    assert serialized_path_to_waypoints(serialize_message(longest)).shape == (MAX_PATH_POSES, 2)
    longest.poses.append(longest.poses[0])
    with pytest.raises(MessageFault, match=f'the path has {MAX_PATH_POSES + 1} poses'):
        serialized_path_to_waypoints(serialize_message(longest))


def test_the_same_path_again_is_recognised_without_reading_it(monkeypatch):
    read = conversions.serialized_path_to_waypoints
    reads = []

    def counted(*args):
        reads.append(args[0])
        return read(*args)

    monkeypatch.setattr(conversions, 'serialized_path_to_waypoints', counted)
    reader = SerializedPathReader('map')
    waypoints = [[0.0, 0.0], [1.0, 0.0]]
    first = serialize_message(make_path(1.0, waypoints, 'map'))
    np.testing.assert_array_equal(reader.read(first), waypoints)
    # A message of the same bytes, as a sender re-publishing its path sends it.
    assert reader.read(bytearray(first)) is None
    assert len(reads) == 1
    # Re-stamped, it is another message: read (the agent keeps the progress along it).
    again = serialize_message(make_path(2.0, waypoints, 'map'))
    np.testing.assert_array_equal(reader.read(again), waypoints)
    refused = serialize_message(make_path(3.0, waypoints, 'odom'))
    for _ in range(2):
        with pytest.raises(MessageFault, match='header.frame_id'):
            reader.read(refused)
    # A refused path does not replace the one read last.
    assert reader.read(again) is None
    assert len(reads) == 4


def test_a_route_is_read_with_its_stamp_and_its_faults_go_to_the_fault_handler():
    """`subscribe_route`'s callback: (stamp, waypoints) to the receiver, a fault to its handler."""
    subscriptions = []

    class Node:
        def create_subscription(self, msg_type, topic, callback, qos, raw, event_callbacks):
            subscriptions.append((msg_type, topic, callback, qos, raw))

    received, faults = [], []
    subscribe_route(Node(), 'robot_1', lambda *args: received.append(args),
                    lambda *args: faults.append(args))
    msg_type, topic, callback, qos, raw = subscriptions[0]
    assert (msg_type, topic, qos, raw) == (Path, '/robot_1/plan', PLAN_READER_QOS, True)
    # Compatible with the publishers' PLAN_QOS (latched), and queued deeper.
    assert (qos.reliability, qos.durability) == (PLAN_QOS.reliability, PLAN_QOS.durability)
    assert qos.depth > PLAN_QOS.depth
    callback(serialize_message(_path(lambda msg: None)))
    ((robot, waypoints, stamp),) = received
    assert (robot, stamp) == ('robot_1', 1.0)
    np.testing.assert_array_equal(waypoints, [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]])
    # An empty route reads as such: the receiver refuses it (the robot claims nothing).
    stamp, waypoints = serialized_route(serialize_message(make_path(2.5, [], 'map')))
    assert stamp == 2.5 and waypoints.shape == (0, 2)
    for data, fault in (
            (serialize_message(_path(lambda msg: setattr(msg.header, 'frame_id', 'odom'))),
             "header.frame_id is 'odom'"),
            (serialize_message(_path(lambda msg: _set(msg, 1, 'y', float('nan')))), 'NaN'),
            (serialize_message(_path(lambda msg: None))[:6], 'truncated'),
            (serialize_message(_path(lambda msg: setattr(msg.header.stamp, 'sec', -1))),
             'path header.stamp is no time')):
        callback(data)
        robot, fault_topic, error = faults[-1]
        assert (robot, fault_topic) == ('robot_1', '/robot_1/plan')
        assert isinstance(error, MessageFault) and fault in str(error), error
    # What the receiver refuses is a fault too.
    subscribe_route(Node(), 'robot_2', _refuse, lambda *args: faults.append(args))
    subscriptions[-1][2](serialize_message(_path(lambda msg: None)))
    assert faults[-1][:2] == ('robot_2', '/robot_2/plan') and str(faults[-1][2]) == 'refused'


def _refuse(robot, waypoints, stamp):
    raise ValueError('refused')
