"""core/interrupts.py: a stop signal is recorded; a second one, of either kind, raises; the
request does not outlive the block that handled it; raising() raises at the first."""

from __future__ import annotations

import os
import signal

import pytest

from swarmscene.core import interrupts


def test_the_first_signal_is_recorded_and_a_second_of_the_other_kind_raises():
    interrupts.clear()
    with interrupts.handle_stop_signals():
        os.kill(os.getpid(), signal.SIGINT)
        assert interrupts.requested() == signal.SIGINT
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGTERM)
    assert interrupts.requested() is None  # a later run in this process starts unrequested


def test_raising_raises_at_the_first_signal_and_on_entry_when_one_is_pending():
    interrupts.clear()
    with interrupts.handle_stop_signals():
        with pytest.raises(KeyboardInterrupt):
            with interrupts.raising():
                os.kill(os.getpid(), signal.SIGTERM)
        assert interrupts.requested() == signal.SIGTERM  # recorded too: the exit status says 143
        with pytest.raises(KeyboardInterrupt):
            with interrupts.raising():
                pass
    assert signal.getsignal(signal.SIGTERM) is not interrupts._record_and_raise
