"""``lit_planner.signals.handling``: the commands' Ctrl-C, ``kill PID`` and hang-up handling."""

from __future__ import annotations

import signal
import threading

from lit_planner import signals


def test_handlers_hold_for_the_block_and_the_previous_ones_come_back() -> None:
    def before(signum: int, frame: object) -> None: ...

    def during(signum: int, frame: object) -> None: ...

    saved = {signum: signal.signal(signum, before) for signum in signals.STOPS}
    try:
        try:
            with signals.handling(signals.STOPS, during):
                assert all(signal.getsignal(s) is during for s in signals.STOPS)
                raise KeyError  # also when the block fails
        except KeyError:
            pass
        assert all(signal.getsignal(s) is before for s in signals.STOPS)
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)


def test_another_thread_installs_nothing() -> None:
    """signal.signal raises ValueError off the main thread; the block runs without handlers."""
    outcome: list[object] = []

    def worker() -> None:
        try:
            with signals.handling(signals.STOPS, lambda *_: None):
                outcome.append(signal.getsignal(signal.SIGTERM))
        except ValueError as error:
            outcome.append(error)

    before = signal.getsignal(signal.SIGTERM)
    thread = threading.Thread(target=worker)
    thread.start()
    thread.join()
    assert outcome == [before]


def test_a_flag_is_set_by_a_signal_that_lands_inside_its_wait() -> None:
    """The nodes' and ``lit up``'s stop flag: set by the handler of a signal sent while the main
    thread waits on it, and it holds no lock a handler could wait for (the last check: a signal
    rarely lands in the moments an Event's wait() holds its lock, so no run of this test could
    show that deadlock). A threading.Event's set() from a handler that ran while the main thread
    held the event's lock (inside wait()) waited for good: a node that ignored SIGTERM from then
    on."""
    import os

    flag = signals.Flag()
    assert not flag.wait(0.0) and not flag.is_set()
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGUSR1))
    with signals.handling([signal.SIGUSR1], flag.set):
        timer.start()
        assert flag.wait(120.0)  # the handler ran in this thread, inside the wait
    timer.join()
    assert flag.is_set()
    flag.clear()
    assert not flag.is_set() and vars(flag) == {"_set": False}  # no lock anywhere
