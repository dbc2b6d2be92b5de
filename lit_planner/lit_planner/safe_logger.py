"""``SafeLogger``: the nodes' logger, which logs any text.

A module of its own: rclpy credits a log call to the first caller outside the files in its
``_internal_callers``, and this file is added there. When it was part of ``rosutil``, every log
call made in ``rosutil`` itself was credited to rclpy's executor line that ran the callback, so
an info and an error of the same callback had one call site, and rclpy raised "Logger severity
cannot be changed between calls" (the node that outlived a duplicate server died of it).
"""

from __future__ import annotations

import os
from typing import Any

from lit_msgs_json.codec import CONTROL_ESCAPES


class SafeLogger:
    """An rclpy logger that logs any text: rclpy raises for a str that is not Unicode text (a lone
    surrogate), and a log call in a worker thread's ``except`` clause then ended the thread (the
    planner node answered no more plan requests). Such characters are logged escaped
    (``\\ud800``), and so are control characters (each record one line, as written); other
    attributes are the logger's own."""

    def __init__(self, logger: Any) -> None:
        self._logger = logger
        # rclpy names the first caller outside its own files as the log's file, line and
        # function (and keys once= and throttle filters on it): without this, every line of
        # both nodes came from here. rclpy's own code invites third parties to add files.
        try:
            from rclpy.impl import rcutils_logger
        except ImportError:
            return
        here = os.path.realpath(__file__)
        if here not in rcutils_logger._internal_callers:
            rcutils_logger._internal_callers.append(here)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._logger, name)

    @staticmethod
    def text(message: object) -> str:
        """``message`` as text that encodes to UTF-8."""
        from lit_msgs_json.envelope import unicode_text

        return unicode_text(str(message)).translate(CONTROL_ESCAPES)

    def debug(self, message: object, **kwargs: Any) -> Any:
        return self._logger.debug(self.text(message), **kwargs)

    def info(self, message: object, **kwargs: Any) -> Any:
        return self._logger.info(self.text(message), **kwargs)

    def warning(self, message: object, **kwargs: Any) -> Any:
        return self._logger.warning(self.text(message), **kwargs)

    warn = warning

    def error(self, message: object, **kwargs: Any) -> Any:
        return self._logger.error(self.text(message), **kwargs)

    def fatal(self, message: object, **kwargs: Any) -> Any:
        return self._logger.fatal(self.text(message), **kwargs)
