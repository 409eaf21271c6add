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


def test_a_calibrated_board_with_a_model_answers_with_all_three_hashes(tmp_path):
    """The check after flashing with --calibration and --model, against that image on the
    virtual board: the three hashes confirmed; another model refused in one line."""
    from delta6.build.flash import reported
    from delta6.commands.codegen import design_firmware

    from support.onchip import calibration_and_model

    baseline = load(DESIGNS / "delta6.toml")
    cal, cal_path, model, model_path = calibration_and_model(baseline, tmp_path)
    image = design_firmware(DESIGNS / "delta6.toml", cal_path, model_path)
    expected = Expected(baseline.name, baseline.hash32(), cal.name, cal.hash32(), model.name,
                        model.hash32())
    with VirtualBoard(image=image, speed=0) as board:
        info = check_board(board.port, expected, baud=DEFAULT_BAUD)
        assert reported(info) == expected
        other = Expected(baseline.name, baseline.hash32(), cal.name, cal.hash32(), "other",
                         model.hash32() ^ 1)
        with pytest.raises(UserError, match=f"reports model '{model.name}' .*, expected model "
                                            "'other'"):
            check_board(board.port, other, baud=DEFAULT_BAUD)
