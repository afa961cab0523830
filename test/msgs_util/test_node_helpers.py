"""Node helpers: parameter declaration, stop signals, throttled warnings, graph discovery."""

import subprocess
import sys
import textwrap

import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter

from prvo_msgs_util import (
    PARAMETER_TYPES,
    ThrottledWarnings,
    declare_parameters,
    parameter_descriptor,
    robots_with_topic,
)
from prvo_planner.parameters import PARAMETERS


def test_every_planner_parameter_kind_has_a_ros_type():
    assert {spec.kind for spec in PARAMETERS.values()} <= set(PARAMETER_TYPES)
    assert PARAMETER_TYPES['float'].value == ParameterType.PARAMETER_DOUBLE
    assert PARAMETER_TYPES['str[]'].value == ParameterType.PARAMETER_STRING_ARRAY


def test_descriptor_ranges_follow_the_kind():
    seconds = parameter_descriptor('a time', 'float', (0.001, 3600.0), read_only=False)
    assert not seconds.read_only and seconds.type == ParameterType.PARAMETER_DOUBLE
    (limits,) = seconds.floating_point_range
    assert (limits.from_value, limits.to_value, limits.step) == (0.001, 3600.0, 0.0)
    assert not seconds.integer_range
    seed = parameter_descriptor('a seed', 'int', (-1, 2**31 - 1))
    assert seed.read_only
    (limits,) = seed.integer_range
    assert (limits.from_value, limits.to_value, limits.step) == (-1, 2**31 - 1, 1)
    name = parameter_descriptor('a name', 'str', dynamic_typing=True)
    assert name.dynamic_typing and not name.floating_point_range and not name.integer_range


def declared(probe, overrides, declarations, is_dumped_unset=None):
    import rclpy

    node = rclpy.create_node('declaring', context=probe.context,
                             parameter_overrides=overrides)
    try:
        return declare_parameters(node, declarations, is_dumped_unset), {
            name: node.describe_parameter(name) for name in declarations}
    finally:
        node.destroy_node()


def test_declared_parameters_take_their_overrides_in_order(probe):
    declarations = {
        'rate': (0.0, parameter_descriptor('rate', 'float', (0.0, 1000.0))),
        'observers': (Parameter.Type.STRING_ARRAY, parameter_descriptor('names', 'str[]')),
        'goal': (None, parameter_descriptor('goal', 'float[]', read_only=True,
                                            dynamic_typing=True)),
    }
    values, descriptors = declared(probe, [Parameter('rate', value=20.0)], declarations)
    assert list(values) == ['rate', 'observers', 'goal']
    assert values == {'rate': 20.0, 'observers': None, 'goal': None}
    assert descriptors['observers'].type == ParameterType.PARAMETER_STRING_ARRAY
    assert descriptors['goal'].read_only
    with pytest.raises(InvalidParameterValueException, match='rate'):
        declared(probe, [Parameter('rate', value=2000.0)], declarations)


def test_a_dumped_null_leaves_a_parameter_unset_and_read_only(probe):
    declarations = {'goal': (None, parameter_descriptor('goal', 'float[]', read_only=True,
                                                        dynamic_typing=True))}

    def is_dumped_unset(name, value):
        return value == 'null'

    values, descriptors = declared(probe, [Parameter('goal', value='null')], declarations,
                                   is_dumped_unset)
    assert values == {'goal': None} and descriptors['goal'].read_only
    values, _ = declared(probe, [Parameter('goal', value=[1.0, 2.0])], declarations,
                         is_dumped_unset)
    assert values == {'goal': [1.0, 2.0]}


class _Logger:
    def __init__(self):
        self.warnings = []

    def warning(self, message):
        self.warnings.append(message)


def test_throttled_warnings_hold_back_repeats_of_a_kind_only():
    logger = _Logger()
    # A period no test run reaches: only the first warning of each kind is logged.
    warnings = ThrottledWarnings(logger, period=3600.0)
    for kind, message in [('goal', 'a'), ('goal', 'b'), (('odom', 'stale'), 'c'), ('goal', 'd'),
                          (('odom', 'stale'), 'e'), (('odom', 'NaN'), 'f')]:
        warnings.warn(kind, message)
    assert logger.warnings == ['a', 'c', 'f']
    every = ThrottledWarnings(logger, period=0.0)
    every.warn('goal', 'g')
    every.warn('goal', 'h')
    assert logger.warnings[-2:] == ['g', 'h']


class _Graph:
    def get_topic_names_and_types(self):
        return [('/robot_0/odom', ['nav_msgs/msg/Odometry']),
                ('/robot_1/odom', ['std_msgs/msg/String']),
                ('/robot_2/odom', ['std_msgs/msg/String', 'nav_msgs/msg/Odometry']),
                ('/robot_3/ground_truth', ['nav_msgs/msg/Odometry']),
                ('/team/robot_4/odom', ['nav_msgs/msg/Odometry']),
                ('/odom', ['nav_msgs/msg/Odometry'])]


def test_robots_with_a_topic_of_the_type_are_found_in_the_graph():
    assert robots_with_topic(_Graph(), 'odom', 'nav_msgs/msg/Odometry') == {
        'robot_0', 'robot_2'}


@pytest.mark.parametrize('send, released', [(False, True), (True, False)])
def test_a_stop_signal_held_back_at_start_is_taken_on_release(send, released):
    script = textwrap.dedent(f"""
        import os, signal
        from prvo_msgs_util import hold_stop_signals, release_stop_signals
        hold_stop_signals()
        if {send}:
            os.kill(os.getpid(), signal.SIGTERM)
        print(release_stop_signals())
    """)
    result = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                            timeout=60)
    # Held, the SIGTERM neither killed the process nor ran a handler.
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == str(released)
