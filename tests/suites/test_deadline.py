"""The in-process step limit (langtraj.suites.deadline): it interrupts a call that runs past it in the main thread,
and says so where it cannot (another thread)."""

from __future__ import annotations

import threading
import time

import pytest

from langtraj.suites.deadline import StepTimeout, deadline


def test_a_call_past_its_limit_is_interrupted():
    with pytest.raises(StepTimeout, match=r"0\.05 s"), deadline(0.05):
        time.sleep(2.0)
    with deadline(1.0):  # a call within its limit runs to its end, and the timer is disarmed after it
        time.sleep(0.01)
    time.sleep(1.1)


def test_off_the_main_thread_the_limit_is_not_enforced_and_says_so():
    caught: list[BaseException] = []

    def call() -> None:
        try:
            with pytest.warns(RuntimeWarning, match="cannot be enforced"), deadline(0.01):
                time.sleep(0.05)
        except BaseException as error:
            caught.append(error)

    worker = threading.Thread(target=call)
    worker.start()
    worker.join()
    assert not caught, caught
