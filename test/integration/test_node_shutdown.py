"""The nodes stop cleanly on Ctrl-C: also when it lands in a callback, or again in teardown."""

import pathlib

import pytest

from prvo_sim.scenario import find_scenario

pytestmark = pytest.mark.integration

HARNESS = pathlib.Path(__file__).with_name('interrupt_in_teardown.py')
IN_CALLBACK = pathlib.Path(__file__).with_name('interrupt_in_callback.py')


@pytest.mark.parametrize('module, arguments, service', [
    ('prvo_planner.planner_node', ['-r', '__ns:=/robot_0', '-p', 'goal:=[1.0, 0.0]'],
     '/robot_0/planner/get_parameters'),
    ('prvo_sim.sim_node', ['-r', '__node:=prvo_sim', '-p', 'mode:=realtime',
                           '-p', f'scenario:={find_scenario("headon2")}'],
     '/prvo_sim/get_parameters'),
])
def test_a_second_sigint_during_teardown_exits_zero_quietly(children, probe, python_executable,
                                                            module, arguments, service):
    from rcl_interfaces.srv import GetParameters

    process = children.start('node', [python_executable, str(HARNESS), module, '--ros-args',
                                      *arguments])
    client = probe.node.create_client(GetParameters, service)
    probe.wait_until(lambda: client.service_is_ready() or process.poll() is not None,
                     timeout=60.0, what=f'{module} up')
    assert process.poll() is None, children.output(process)
    assert children.interrupt(process, timeout=30.0) == 0, children.output(process)
    assert 'Traceback' not in children.output(process), children.output(process)


@pytest.mark.parametrize('module, arguments', [
    ('prvo_planner.planner_node', ['-r', '__ns:=/robot_0', '-p', 'goal:=[1.0, 0.0]']),
    ('prvo_sim.sim_node', ['-r', '__node:=prvo_sim', '-p', 'mode:=realtime',
                           '-p', f'scenario:={find_scenario("headon2")}']),
    ('prvo_sim.upstream_node', ['-r', '__ns:=/robot_0', '-p', 'waypoints:=[1.0, 0.0]']),
])
def test_a_sigint_inside_a_callback_exits_zero_quietly(children, python_executable, module,
                                                       arguments):
    # A KeyboardInterrupt raised in a callback is logged by the events executor as FATAL with
    # a traceback; in a message's constructor, called by rclpy's deserialization, it turns into
    # a TypeError. The stop must come through rclpy's shutdown instead.
    process = children.start('node', [python_executable, str(IN_CALLBACK), module,
                                      '--ros-args', *arguments])
    assert process.wait(timeout=60) == 0, children.output(process)
    output = children.output(process)
    assert 'Traceback' not in output and 'FATAL' not in output, output
