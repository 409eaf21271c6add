"""The check ``delta6 flash`` makes after an upload, against the real firmware on the virtual
board: it confirms the design the image was built for and refuses another."""
from __future__ import annotations

import pytest

from delta6.build.flash import Expected, check_board
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.link.device import DEFAULT_BAUD
from delta6.sim.virtualboard import VirtualBoard, firmware

from conftest import DESIGNS


def test_the_virtual_board_answers_with_its_design_hash():
    baseline, stiff = load(DESIGNS / "delta6.toml"), load(DESIGNS / "stiff.toml")
    with VirtualBoard(image=firmware(), speed=0) as board:
        info = check_board(board.port, Expected(baseline.name, baseline.hash32()),
                           baud=DEFAULT_BAUD)
        assert info.design_hash == baseline.hash32() and info.design_name == "delta6"
        with pytest.raises(UserError, match="reports design 'delta6' .* expected design 'stiff'"):
            check_board(board.port, Expected(stiff.name, stiff.hash32()), baud=DEFAULT_BAUD)
