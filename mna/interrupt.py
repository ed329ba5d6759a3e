"""Graceful stops for long loops: Ctrl-C (SIGINT) and SIGTERM (what ``timeout``, schedulers
and ``kill`` send) ask the loop to stop after its current step, so the saved state is always
whole; a second signal aborts at once.

Exit codes follow the shell's ``128 + signal number``: 130 after SIGINT, 143 after SIGTERM,
so a scheduler can tell "stopped and checkpointed" from a failure (1 or 2).
"""
from __future__ import annotations

import contextlib
import signal
from typing import Iterator

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """SIGTERM outside a graceful loop: raised like Ctrl-C's ``KeyboardInterrupt`` so the same
    cleanup runs (atomic writes remove their temporaries) and the CLI exits with 143."""


def exit_code(signum: int) -> int:
    """``128 + signum``: 130 for SIGINT, 143 for SIGTERM."""
    return 128 + int(signum)


class StopFlag:
    """Set by SIGINT/SIGTERM while :func:`graceful_stop` is active; the loop polls ``requested``."""

    def __init__(self) -> None:
        self.requested = False
        self.signum: int | None = None
        """the signal that asked for the stop (None while running or when stopped otherwise)."""


def _raise_for(signum: int):
    raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt


def on_sigterm_raise(signum, frame):
    """SIGTERM handler for the CLI: behave like Ctrl-C (see :class:`Terminated`)."""
    raise Terminated


@contextlib.contextmanager
def graceful_stop(enabled: bool = True) -> Iterator[StopFlag]:
    """Install the handlers for the ``with`` block (not possible outside the main thread:
    then the signals keep their previous meaning)."""
    flag = StopFlag()

    def on_signal(signum, frame):
        if flag.requested:
            _raise_for(signum)
        flag.requested, flag.signum = True, signum

    previous = {}
    if enabled:
        for sig in STOP_SIGNALS:
            try:
                previous[sig] = signal.signal(sig, on_signal)
            except ValueError:  # not the main thread
                break
    try:
        yield flag
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


#: the old name (SIGTERM is handled too now)
graceful_sigint = graceful_stop
