"""The simulator's parameter rules, without a node."""

import pytest

from prvo_sim.sim_parameters import PARAMETERS, parameter_fault


@pytest.mark.parametrize('name, value, fault', [
    ('mode', 'fast', "mode must be one of lockstep, realtime, got 'fast'"),
    ('scenario', '', 'scenario is required (a YAML path or a name)'),
    ('observers', ['/prvo_run_recorder_1', 'recorder'],
     "observers: 'recorder' does not start with / (like '/prvo_run_recorder_1234')"),
])
def test_a_refused_value_is_named(name, value, fault):
    assert parameter_fault(name, value) == fault


@pytest.mark.parametrize('name, value', [
    ('mode', 'lockstep'), ('mode', 'realtime'), ('scenario', 'headon2'), ('observers', None),
    ('observers', ['/ns/recorder']), ('rate', 0.0)])
def test_an_accepted_value_has_no_fault(name, value):
    assert parameter_fault(name, value) is None


def test_only_the_timeouts_of_a_running_step_can_change():
    writable = {name for name, (_, descriptor) in PARAMETERS.items() if not descriptor.read_only}
    assert writable == {'step_timeout', 'cmd_timeout'}
    _, cmd_timeout = PARAMETERS['cmd_timeout']
    assert cmd_timeout.floating_point_range[0].from_value == 1e-6
