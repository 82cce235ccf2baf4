"""arenabench.interrupts: real signals sent to this process."""

import os
import signal

import pytest

from arenabench.interrupts import Interrupted, catch_interrupts


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_first_signal_raises_later_ones_are_recorded_and_handlers_restored(signum, code):
    before = signal.getsignal(signum)
    with catch_interrupts() as state:
        with pytest.raises(Interrupted) as info:
            os.kill(os.getpid(), signum)
            signal.sigtimedwait([], 0)  # let the handler run
        assert (info.value.signum, info.value.exit_code) == (signum, code)
        os.kill(os.getpid(), signal.SIGINT)  # while cleaning up: not raised
        assert state.interrupted and state.exit_code == code and state.event.is_set()
    assert signal.getsignal(signum) == before


def test_flag_mode_only_sets_the_state():
    with catch_interrupts(raise_exception=False) as state:
        os.kill(os.getpid(), signal.SIGTERM)
        assert state.event.wait(5)
    assert state.signum == signal.SIGTERM and state.exit_code == 143
