"""Signal handlers installed for the length of a block: how the commands stop on Ctrl-C,
``kill PID`` and the terminal closing."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from typing import Any

STOPS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""What stops a command: Ctrl-C, ``kill PID``, the terminal closing."""


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
