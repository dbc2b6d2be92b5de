"""Signal handlers installed for the length of a block: how the commands stop on Ctrl-C,
``kill PID`` and the terminal closing."""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

STOPS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""What stops a command: Ctrl-C, ``kill PID``, the terminal closing."""


class Flag:
    """A flag that a signal handler may set (``signal.signal(SIGTERM, flag.set)``), and that the
    main thread waits on: neither takes a lock.

    A :class:`threading.Event` will not do: its ``wait()`` holds the event's (not reentrant) lock
    for moments, and a signal handled in one of them, in the main thread, runs a ``set()`` that
    waits for that lock for good. A node then no longer stopped on SIGTERM (a recorder, in 2 of 10
    tries, left recording the next run into its bag)."""

    POLL = 0.02
    """Seconds between looks while :meth:`wait` waits."""

    def __init__(self) -> None:
        self._set = False

    def set(self, *_: object) -> None:
        """Set the flag (a signal handler's arguments are ignored)."""
        self._set = True

    def clear(self) -> None:
        self._set = False

    def is_set(self) -> bool:
        return self._set

    def wait(self, timeout: float) -> bool:
        """Whether the flag is set, waiting up to ``timeout`` s for it."""
        deadline = time.monotonic() + timeout
        while not self._set:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(left, self.POLL))
        return True


@contextlib.contextmanager
def handling(signums: Iterable[int], handler: Callable[[int, Any], Any]) -> Iterator[None]:
    """Install ``handler`` for ``signums`` while the block runs, then put the previous handlers
    back. Signal handlers belong to the main thread: from any other nothing is installed. A
    previous handler set outside Python (``signal.signal`` returns None for it) cannot be put
    back and stays replaced."""
    previous: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for signum in signums:
            previous[signum] = signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, handler_before in previous.items():
            if handler_before is not None:
                signal.signal(signum, handler_before)
