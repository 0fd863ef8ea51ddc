"""The per-step time limit of an in-process planner (docs/testing.md, 'Scenario suites').

`deadline(seconds)` arms SIGALRM (`signal.setitimer(ITIMER_REAL)`) around one planner call; when the call runs
past its limit the handler raises `StepTimeout` inside it. `StepTimeout` derives from BaseException, so a planner's
own `except Exception:` cannot swallow it. Limits: signals are delivered only to the main thread of the process,
between Python bytecodes; elsewhere (a worker thread, a platform without SIGALRM) the call runs unguarded, with a
RuntimeWarning, and a planner stuck inside C code that does not return to the interpreter (a native library's busy
loop) cannot be interrupted in-process. `langtraj test --planner-cmd CMD` runs the planner in a process of its
own, which its time limit ends whatever it is doing.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import warnings
from collections.abc import Iterator


class StepTimeout(BaseException):  # a BaseException, so that planners' `except Exception` miss it
    """An in-process planner call ran past its limit."""


def can_interrupt() -> bool:
    """Whether `deadline` can interrupt a call here: SIGALRM exists and this is the main thread."""
    return hasattr(signal, "SIGALRM") and threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def deadline(seconds: float | None) -> Iterator[None]:
    """Raise `StepTimeout` in the block when it runs longer than `seconds` (None or <= 0: no limit; see the
    module's docstring for where it cannot interrupt). The previous SIGALRM handler and timer are restored."""
    if not seconds or seconds <= 0:
        yield
        return
    if not can_interrupt():
        warnings.warn(
            f"the planner's {seconds:g}-s step limit cannot be enforced here (not the main thread, or no SIGALRM); "
            "run the planner with --planner-cmd to enforce it",
            RuntimeWarning,
            stacklevel=3,
        )
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise StepTimeout(f"no answer within {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
