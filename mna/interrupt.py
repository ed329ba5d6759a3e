"""Graceful Ctrl-C for long loops: the first SIGINT asks the loop to stop after its current
step (so the saved state is always whole); a second one aborts at once."""
from __future__ import annotations

import contextlib
import signal
from typing import Iterator


class StopFlag:
    """Set by SIGINT while :func:`graceful_sigint` is active; the loop polls ``requested``."""

    def __init__(self) -> None:
        self.requested = False


@contextlib.contextmanager
def graceful_sigint(enabled: bool = True) -> Iterator[StopFlag]:
    """Install the handler for the ``with`` block (not possible outside the main thread:
    then Ctrl-C keeps its plain ``KeyboardInterrupt`` meaning)."""
    flag = StopFlag()

    def on_sigint(signum, frame):
        if flag.requested:
            raise KeyboardInterrupt
        flag.requested = True

    previous = None
    if enabled:
        try:
            previous = signal.signal(signal.SIGINT, on_sigint)
        except ValueError:
            previous = None
    try:
        yield flag
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
