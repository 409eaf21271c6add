"""The wait for the next samples: a device that falls silent is named as such, and one that
restarted meanwhile (it boots idle) is told apart from one that stopped streaming."""
from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest

from delta6.commands._port import next_block
from delta6.link.device import SampleTimeout


class SilentDevice:
    """No samples; ``boots`` restarts shown after the first read."""

    port = "/dev/pts/9"

    def __init__(self, boots: int):
        self.reads, self.boots = 0, boots

    def read_block(self, timeout):
        self.reads += 1
        raise SampleTimeout("nothing")

    @property
    def health(self):
        shown = self.boots if self.reads else 0
        return SimpleNamespace(device_resets=shown, restarts=0)

    def info(self):
        return SimpleNamespace(rate_hz=250)


@pytest.mark.parametrize("boots,words", [(0, "did the device stop streaming?"),
                                         (1, "the device restarted meanwhile and boots idle")])
def test_silence_says_why_it_may_be(boots, words):
    with pytest.raises(SampleTimeout) as err:
        next_block(SilentDevice(boots), threading.Event(), patience=0.05)
    assert words in str(err.value) and "/dev/pts/9" in str(err.value)
