"""Standard output whose write errors, other than a broken pipe, are :class:`StdoutError`, so
that ``lit`` can tell an answer it could not print from a command's own file errors."""

from __future__ import annotations

from typing import Any


class StdoutError(Exception):
    """Standard output could not be written (a full disk behind ``> file``, ``> /dev/full``)."""


class GuardedStdout:
    """``sys.stdout`` whose write errors other than a broken pipe are :class:`StdoutError`: a
    command's own file errors stay OSErrors, and an answer that could not be printed is one line
    (it was a traceback and exit 1, which ``lit plan`` uses for "not solved")."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as error:
            raise StdoutError(error) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as error:
            raise StdoutError(error) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)
