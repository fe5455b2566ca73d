"""A background thread running one step function until stopped."""

from __future__ import annotations

import threading
from collections.abc import Callable


class BackgroundLoop:
    """Runs ``step()`` again and again in a daemon thread named ``name`` until `stop`.

    An exception of a step goes to ``on_error(exc)`` and the loop waits ``pause`` [s] before
    the next step: the loop outlives any surprise.
    """

    def __init__(self, name: str, step: Callable[[], None],
                 on_error: Callable[[Exception], None], pause: float) -> None:
        self.name = name
        self._step = step
        self._on_error = on_error
        self._pause = pause
        self.stopping = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        """True while the thread is alive."""
        thread = self._thread
        return thread is not None and thread.is_alive()

    def start(self) -> None:
        """Start the thread (no-op while it runs)."""
        if self.running:
            return
        self.stopping.clear()
        self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> bool:
        """Stop the thread, waiting up to ``timeout`` [s] (no-op when it does not run).

        Returns False when the thread is still alive after ``timeout``.
        """
        thread, self._thread = self._thread, None
        if thread is None:
            return True
        self.stopping.set()
        if thread is not threading.current_thread():
            thread.join(timeout)
            return not thread.is_alive()
        return True

    def _run(self) -> None:
        while not self.stopping.is_set():
            try:
                self._step()
            except Exception as exc:
                self._on_error(exc)
                self.stopping.wait(self._pause)
