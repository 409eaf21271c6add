"""``delta6 virtual --design`` with a narrow joint box: the demo motion stays in the box, and
the twin simulates every valid design (or says in one line why not). The firmware build and
the emulator are stood in for: what is checked is what the command feeds them."""
from __future__ import annotations

import re

import numpy as np
import pytest

from delta6.cli import main
from delta6.commands import codegen
from delta6.core.errors import UserError
from delta6.link.protocol import counts_to_theta
from delta6.sim import virtualboard as vb

from conftest import DESIGNS


def narrow_design(tmp_path, limit):
    text = (DESIGNS / "delta6.toml").read_text()
    text = re.sub(r"(?m)^name = .*$", 'name = "narrow"', text)
    path = tmp_path / "narrow.toml"
    path.write_text(text + f"\njoint_limit_rad = {limit}\n")
    return path


class Seen(UserError):
    """Raised by the stand-in board once it has seen its arguments."""


@pytest.fixture
def board_inputs(monkeypatch):
    """What the command hands the virtual board: the demo replay's angles, or the live flag."""
    seen = {}

    def fake_board(**kwargs):
        replay = kwargs["replay"]
        if replay is not None:
            raw = replay.read_bytes()[len(vb.REPLAY_MAGIC) + 8:]
            records = np.frombuffer(raw, dtype=[("t", "<f8"), ("c", "<u2", (6,))])
            seen["theta"] = counts_to_theta(records["c"], kwargs["zero"])
        seen["live"] = kwargs["live"]
        raise Seen("stand-in board")

    monkeypatch.setattr(codegen, "design_firmware", lambda *a, **k: object())
    monkeypatch.setattr(vb, "VirtualBoard", fake_board)
    return seen


@pytest.mark.parametrize("limit", [0.02, 0.3])
def test_the_demo_motion_stays_inside_the_designs_joint_box(tmp_path, board_inputs, limit):
    assert main(["virtual", "--design", str(narrow_design(tmp_path, limit))]) == 2
    theta = board_inputs["theta"]
    assert np.abs(theta).max() <= limit        # every streamed sample is in the box ...
    assert np.abs(theta).max() > 0.2 * limit   # ... and the demo still moves across it


@pytest.mark.parametrize("limit", [0.01, 0.015, 0.022])
def test_the_twin_drives_a_board_of_a_narrow_box(tmp_path, board_inputs, limit, capsys):
    assert main(["virtual", "--design", str(narrow_design(tmp_path, limit)), "--twin", "paper",
                 "--twin-duration", "2"]) == 2
    assert board_inputs["live"] is True
    assert "stand-in board" in capsys.readouterr().err


def test_a_design_the_twin_refuses_is_one_line(tmp_path, board_inputs, monkeypatch, capsys):
    from delta6 import twin

    def refuse(*args, **kwargs):
        raise ValueError("something the twin cannot do")

    monkeypatch.setattr(twin, "simulate", refuse)
    assert main(["virtual", "--design", str(narrow_design(tmp_path, 0.3)), "--twin",
                 "ideal"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "something the twin cannot do" in err[-1] and "Traceback" not in "\n".join(err)
    assert "'narrow'" in err[-1]
