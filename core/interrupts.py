"""Stop requests (Ctrl-C, SIGTERM) recorded by a signal handler and acted on between ticks.

A handler that raises (Python's default for SIGINT) can land anywhere: inside a numba-compiled
kernel (numba then reports ``SystemError: CPUDispatcher(...) returned a result with an exception
set``), in the middle of a file being written, or while Hydra makes the run directory. So the
handler installed by :func:`handle_stop_signals` only records which signal came; the places that
can stop cleanly ask :func:`requested`: the stepping loop between two ticks
(:meth:`swarmscene.core.simulation.Simulation.run`), and the command line before and after each
phase (composition, build, run, writing).

A second stop signal (of either kind) while the first is still pending raises ``KeyboardInterrupt``
at once: the escape hatch when the first one is not acted on soon enough (a long compile, a
blocking write). Where raising is safe at any moment (the main process of a sweep whose jobs run
in other processes), :func:`raising` makes the first signal raise.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_requested: int | None = None
"""The first stop signal received and not yet cleared (its number), else None."""


def requested() -> int | None:
    """The stop signal received (``signal.SIGINT`` or ``signal.SIGTERM``), or None."""
    return _requested


def request(signum: int = signal.SIGINT) -> None:
    """Record a stop request, as the handler does (for code that stops a run without a signal)."""
    global _requested
    if _requested is None:
        _requested = int(signum)


def clear() -> None:
    """Forget a recorded request (a new run in the same process starts unrequested)."""
    global _requested
    _requested = None


def _record(signum: int, frame: Any) -> None:
    """The handler: record the request; only a second one raises (see the module's note)."""
    if _requested is not None:
        raise KeyboardInterrupt
    request(signum)


def _record_and_raise(signum: int, frame: Any) -> None:
    request(signum)
    raise KeyboardInterrupt


def install() -> bool:
    """Install the recording handler for SIGINT and SIGTERM (main thread only); True when done."""
    if threading.current_thread() is not threading.main_thread():
        return False
    for signum in STOP_SIGNALS:
        signal.signal(signum, _record)
    return True


@contextmanager
def handle_stop_signals() -> Iterator[bool]:
    """Within the block, SIGINT and SIGTERM are recorded (:func:`requested`) instead of raising;
    the previous handlers come back after it. Yields False (and changes nothing) off the main
    thread, where Python cannot install handlers."""
    if threading.current_thread() is not threading.main_thread():
        yield False
        return
    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    install()
    try:
        yield True
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
        clear()  # the request was acted on: a later run in this process starts unrequested


@contextmanager
def raising() -> Iterator[None]:
    """Within the block a stop signal is recorded and raises ``KeyboardInterrupt`` at once (for
    code that only waits on other processes: no compiled kernel, no half-written file here); a
    request recorded before the block raises on entry. Off the main thread: nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _requested is not None:
        raise KeyboardInterrupt
    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    for signum in STOP_SIGNALS:
        signal.signal(signum, _record_and_raise)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
