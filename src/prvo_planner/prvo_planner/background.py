"""
One background worker of daemon thread: long work beside a node's callbacks, never in its way.

`concurrent.futures.ThreadPoolExecutor` joins its threads when the interpreter exits, so a
planner asked to stop while it builds a large map waited for the build to finish (16 s for a
2500 x 2500 grid after Ctrl-C). `BackgroundWorker` runs one task at a time, in order, on a
daemon thread: at exit the work in progress is dropped with the process.
"""

import concurrent.futures
import queue
import threading


class BackgroundWorker:
    """Runs submitted calls one at a time, in order, on a daemon thread.

    `submit(function, *args)` returns a `concurrent.futures.Future` of the call's result;
    `shutdown()` cancels the calls not started. The thread starts with the first call.
    """

    def __init__(self, name):
        self._name = name
        self._tasks = queue.SimpleQueue()
        self._thread = None
        self._lock = threading.Lock()

    def submit(self, function, *args):
        """Queue FUNCTION(*ARGS); return the Future of its result."""
        future = concurrent.futures.Future()
        self._tasks.put((future, function, args))
        with self._lock:
            if self._thread is None:
                self._thread = threading.Thread(target=self._work, name=self._name, daemon=True)
                self._thread.start()
        return future

    def shutdown(self):
        """Cancel every call not started; the one running is let go (its thread is a daemon)."""
        while True:
            try:
                future, _, _ = self._tasks.get_nowait()
            except queue.Empty:
                return
            future.cancel()

    def _work(self):
        while True:
            future, function, args = self._tasks.get()
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(function(*args))
            except BaseException as error:  # noqa: B036 - the Future carries it to the caller
                future.set_exception(error)
