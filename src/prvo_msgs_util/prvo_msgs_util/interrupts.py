"""Telling a Ctrl-C shutdown apart from a real error in a node's main()."""

import signal


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
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, signal.SIG_IGN)
