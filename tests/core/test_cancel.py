"""The cancellation: recorded once, raised by check_cancel, deferred to the end of the outermost held block."""

import pytest

from inscal.core import cancel as cc


class _Stop(Exception):
    pass


def test_a_cancellation_inside_held_blocks_is_raised_when_the_outermost_ends(monkeypatch):
    monkeypatch.setattr(cc, "_CANCEL", [])
    cc.check_cancel()  # nothing pending: nothing raised
    assert not cc.holding()
    reached = []
    with pytest.raises(_Stop):
        with cc.signals_held():
            with cc.signals_held():
                assert cc.holding()
                cc.cancel(_Stop("first"))
                cc.cancel(_Stop("second"))  # the first one stays
            reached.append("inner ended without raising")
    assert reached == ["inner ended without raising"]
    assert not cc.holding()
    with pytest.raises(_Stop, match="first"):
        cc.check_cancel()
