"""A Ctrl-C that lands while rclpy deserializes a message still ends the run as a Ctrl-C.

rclpy's deserialization calls each message class's Python constructor from C; a signal handled
there raises the handler's exception inside that call, and pybind11 hands it to the caller as a
TypeError. These tests land a real SIGINT inside the constructor that deserialization calls.
"""

import contextlib
import json
import os
import signal

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from runner_testing import HEADON

from prvo_sim import engine
from prvo_sim.runner import inprocess
from prvo_sim.runner.command_line import build_parser, run_interruptibly
from prvo_sim.runner.processes import INTERRUPTS, RunInterruptedError, untranslated
from prvo_sim.runner.recorder import Recorder
from prvo_sim.runner.session import RunSpec
from prvo_sim.scenario import load_scenario

DIAGNOSTICS = serialize_message(DiagnosticArray(status=[DiagnosticStatus(
    name='prvo_planner/robot_0', values=[KeyValue(key='plan_time_ms', value='1.0')])]))


@contextlib.contextmanager
def interrupt_gate():
    """Install the runner's handler for SIGINT, as `run_interruptibly` does."""
    previous = signal.signal(signal.SIGINT, INTERRUPTS.handle)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def sigint_in_constructor(message_type, after=0):
    """Send SIGINT from within MESSAGE_TYPE's constructor, on its call number AFTER + 1."""
    original = message_type.__init__
    calls = []

    def constructor(self, **fields):
        calls.append(None)
        if len(calls) == after + 1:
            # Handled at the next instruction: in this Python frame, which C called.
            os.kill(os.getpid(), signal.SIGINT)
        original(self, **fields)

    message_type.__init__ = constructor
    try:
        yield calls
    finally:
        message_type.__init__ = original


def test_rclpy_hands_an_exception_raised_in_a_constructor_on_as_a_type_error():
    # The premise: without the guard, the Ctrl-C is lost in a TypeError.
    with interrupt_gate(), sigint_in_constructor(KeyValue):
        with pytest.raises(TypeError) as raised:
            deserialize_message(DIAGNOSTICS, DiagnosticArray)
    assert isinstance(raised.value.__cause__, RunInterruptedError)


def test_the_guard_restores_the_interrupt():
    with interrupt_gate(), sigint_in_constructor(KeyValue):
        with pytest.raises(RunInterruptedError) as raised, untranslated():
            deserialize_message(DIAGNOSTICS, DiagnosticArray)
    assert raised.value.signum == signal.SIGINT


def test_the_guard_passes_other_errors_on_unchanged():
    def refuse(self, **fields):
        raise ValueError('a constructor that refuses')

    original = KeyValue.__init__
    KeyValue.__init__ = refuse
    try:
        with pytest.raises(TypeError) as raised, untranslated():
            deserialize_message(DIAGNOSTICS, DiagnosticArray)
    finally:
        KeyValue.__init__ = original
    assert isinstance(raised.value.__cause__, ValueError)


def test_the_recorder_decoding_diagnostics_raises_the_interrupt():
    # The ROS run's path: the runner decodes what its listener streams to it.
    recorder = Recorder.__new__(Recorder)
    recorder._serialized_diagnostics = []
    recorder._routes = [recorder._on_diagnostics]
    with interrupt_gate(), sigint_in_constructor(KeyValue):
        with pytest.raises(RunInterruptedError):
            recorder._handle('messages', [(0, DIAGNOSTICS)])


def deserializing_with_sigint(call):
    """Return a deserialize_message that lands SIGINT in its call number CALL (from 1)."""
    calls = []

    def deserialize(data, message_type):
        calls.append(message_type)
        if len(calls) == call:
            with sigint_in_constructor(message_type):
                return deserialize_message(data, message_type)
        return deserialize_message(data, message_type)

    return deserialize, calls


def inprocess_headon(tmp_path):
    scenario = load_scenario(HEADON)
    options = build_parser().parse_args([HEADON, '--engine', 'inprocess', '--quiet',
                                         '--no-animation', '--no-bag'])
    return RunSpec(options, scenario, 0.8, scenario.seed, tmp_path / 'out')


def test_an_inprocess_run_interrupted_in_deserialization_ends_interrupted_with_results(
        tmp_path, monkeypatch):
    # The engine deserializes each announcement as a subscriber would: in headon2 the two
    # footprints and shares while the team is built (calls 1-4), then the shares that change.
    deserialize, calls = deserializing_with_sigint(5)
    monkeypatch.setattr(engine, 'deserialize_message', deserialize)
    with interrupt_gate():
        result = inprocess.run_inprocess(inprocess_headon(tmp_path))
    assert len(calls) == 5, 'the signal did not land in the fifth deserialization'
    assert result.interrupted == signal.SIGINT
    recorded = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert recorded['ending'] == 'interrupted'
    assert recorded['failure'] == 'interrupted by SIGINT'


def test_an_interrupt_while_the_team_is_built_exits_as_interrupted(tmp_path, monkeypatch):
    deserialize, calls = deserializing_with_sigint(1)
    monkeypatch.setattr(engine, 'deserialize_message', deserialize)
    spec = inprocess_headon(tmp_path)
    code = run_interruptibly('run_scenario', lambda: inprocess.run_inprocess(spec))
    assert calls and code == 128 + signal.SIGINT
