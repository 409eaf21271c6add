"""End to end: calibrate a twin run, build the calibrated firmware, stream from the virtual
board, and compare with the Python calibrated model on the counts the board latched."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

from delta6 import twin
from delta6.calibration import calibrate
from delta6.commands.codegen import design_firmware
from delta6.core import calibration as C
from delta6.core.calibrated import CalibratedModel
from delta6.core.spec import full_scale
from delta6.evaluation.boardstream import stream_log
from delta6.sim.virtualboard import firmware

from conftest import DESIGNS

DESIGN = DESIGNS / "delta6.toml"
EFFECTS = ["stiffness_mismatch", "encoder_offset", "backlash", "joint_friction",
           "spring_hysteresis"]


@pytest.fixture(scope="module")
def unit(baseline, tmp_path_factory):
    effects = [twin.make_effect(name, 21, magnitude=0.8) for name in EFFECTS]
    fit_run = twin.simulate(baseline, effects, duration_s=45, rate_hz=50, seed=21)
    cal = calibrate(fit_run, baseline, effects=EFFECTS, name="e2e-unit").calibration
    path = C.save(cal, tmp_path_factory.mktemp("unit") / "unit.toml")
    return fit_run.truth, cal, path


def test_the_board_streams_the_python_calibrated_wrench(baseline, unit):
    truth, cal, path = unit
    image = design_firmware(DESIGN, path)
    check = twin.simulate(duration_s=4, rate_hz=200, **twin.same_unit(truth, 22))
    run = stream_log(image, check, rate_hz=200, hold_s=2.0)
    # The board says which calibration it applies.
    assert run.info.calibration_hash == cal.hash32() and run.info.calibration_name == "e2e-unit"
    assert run.matched == 1.0 and run.stats["timing"]["missed_ticks"] == 0
    assert np.all(run.status & 0x00FF == 0)
    fs = full_scale(baseline)
    python, _ = CalibratedModel(baseline, cal).run(run.delta, 1.0 / 200)
    # Same numbers: float32 on the AVR and the wire's quantum against float64 on the host.
    assert np.max(np.abs(run.wrench - python) / fs * 100) < 0.01
    moving = run.rows >= 0
    ref = check.wrench[run.rows[moving]]
    board = np.abs(run.wrench[moving] - ref) / fs
    analytical = np.abs(check.model_wrench()[run.rows[moving]] - ref) / fs
    # ... and a better estimate than the analytical model (4 s: near the noise floor on some
    # axes, so the whole squared error is compared).
    assert (board ** 2).sum() < 0.3 * (analytical ** 2).sum()


def test_without_a_calibration_the_firmware_is_the_uncalibrated_image(unit):
    committed = firmware()
    rebuilt = design_firmware(DESIGN)
    digest = [hashlib.sha256(im.elf.with_suffix(".hex").read_bytes()).hexdigest()
              for im in (committed, rebuilt)]
    assert digest[0] == digest[1]
