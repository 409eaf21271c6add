"""The virtual board's replay starts with a hold; on a busy machine the stream may start after
it. stream_log then retries with a longer hold, and gives up with one line."""
from __future__ import annotations

import pytest

from delta6.core.errors import UserError
from delta6.evaluation import boardstream


def test_a_late_start_is_retried_with_a_longer_hold(monkeypatch):
    holds = []

    def once(image, log, *, hold_s, **kw):
        holds.append(hold_s)
        return None if len(holds) < 2 else "run"

    monkeypatch.setattr(boardstream, "_stream_once", once)
    assert boardstream.stream_log("image", "log", hold_s=2.0) == "run"
    assert holds == [2.0, 4.0]


def test_every_attempt_late_is_one_clear_error(monkeypatch):
    holds = []
    monkeypatch.setattr(boardstream, "_stream_once",
                        lambda image, log, *, hold_s, **kw: holds.append(hold_s))
    with pytest.raises(UserError, match="initial hold") as err:
        boardstream.stream_log("image", "log", hold_s=1.5)
    assert holds == [1.5, 3.0, 6.0][:boardstream.START_ATTEMPTS]
    assert "\n" not in str(err.value)
