"""Stop signals in a node's main(): held while it starts, told apart from real errors."""

import signal

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class SigintRecorder:
    """
    Remember that SIGINT arrived, keeping Python's KeyboardInterrupt.

    Install it before ``rclpy.init()``: rclpy's own handler wakes the executor and then calls
    the handler it found, this one. rclpy shuts its context down on another thread, so a
    message take in flight when Ctrl-C lands can fail with a RuntimeError while ``rclpy.ok()``
    is still true; ``received`` says that the failure is the shutdown that was asked for.

    Only the first SIGINT raises: a second one (``ros2 launch`` and the terminal both pass
    Ctrl-C on) would land in the node's teardown and end it with a traceback.
    """

    def __init__(self):
        self.received = False

    def install(self):
        """Make this the process's Python SIGINT handler; return self."""
        signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def _on_sigint(self, signum, frame):
        if self.received:
            return
        self.received = True
        raise KeyboardInterrupt


def ignore_stop_signals():
    """
    Ignore SIGINT and SIGTERM from now on: call it last in main(), after rclpy.try_shutdown().

    The node is stopped, so a further signal (``ros2 launch`` and the terminal both pass Ctrl-C
    on) has nothing left to stop. A Python handler would not do: while the interpreter
    finalizes, Python gives such a signal its default action back, and one landing while the
    middleware tears down would kill the process (exit code -2). An ignored one stays ignored.
    """
    for signal_number in STOP_SIGNALS:
        signal.signal(signal_number, signal.SIG_IGN)


def hold_stop_signals():
    """
    Hold SIGINT and SIGTERM back until `release_stop_signals()`; call first in main().

    A stop signal landing while rcl initialises, or just after rclpy installed its handlers,
    was lost now and then, leaving a node that ignored it. Threads started meanwhile (DDS)
    inherit the mask, so afterwards the main thread receives every stop signal.

    The Python handlers of both signals are made to do nothing: rclpy's handlers, installed by
    init(), shut the context down (which ends spinning) and then call these. Python's default, a
    KeyboardInterrupt, would land inside whatever callback is running, which the events
    executor reports as a FATAL exception with a traceback.
    """
    for signal_number in STOP_SIGNALS:
        signal.signal(signal_number, lambda signal_number, frame: None)
    signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)


def release_stop_signals():
    """Let stop signals in again; return False if one came while they were held.

    One that came is taken here, without a handler: the node is to stop before spinning, and
    the signals stay held.
    """
    if signal.sigtimedwait(STOP_SIGNALS, 0) is not None:
        return False
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    return True
