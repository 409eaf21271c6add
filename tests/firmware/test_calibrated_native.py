"""The firmware's calibrated model (delta6_calibrated.cpp, compiled natively) against the Python
reference delta6.core.calibrated: within 0.01 % FS over the joint box and along trajectories,
the history included; property-tested over random calibrations."""
from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6 import twin
from delta6.build.nativecalibrated import native_calibrated
from delta6.core import calibration as C
from delta6.core.calibrated import CalibratedModel, counts_from_angles
from delta6.core.spec import full_scale
from delta6_codegen.calibration_header import (
    CalibrationRangeError,
    calibration_constants,
    curve_constants,
)

from support.calibrations import random_calibration, with_curves

TOLERANCE_PCT = 0.01


def random_path(seed: int, n: int, limit: int) -> np.ndarray:
    """Counts inside the box: random walks with reversals and jumps (history exercised), with
    steps on both sides of the speed filter's table of steps (kSpeedSteps, 8 counts)."""
    rng = np.random.default_rng(seed)
    steps = rng.integers(-12, 13, size=(n, 6)) * (rng.random((n, 1)) < 0.9)
    jumps = (rng.random((n, 6)) < 0.01) * rng.integers(-300, 301, size=(n, 6))
    return np.clip(np.cumsum(steps + jumps, axis=0) + rng.integers(-limit, limit, 6),
                   -limit, limit)


@pytest.fixture(scope="module")
def libdir(tmp_path_factory):
    return tmp_path_factory.mktemp("calibrated")


def worst_pct(design, cal, counts, period, libdir, **kw) -> float:
    native = native_calibrated(design, cal, period, libdir, **kw)
    c_wrench, status = native.run(counts)
    py, _ = CalibratedModel(design, cal).run(counts, period)
    assert np.all(status == 0)
    return float((np.abs(c_wrench - py) / full_scale(design) * 100).max())


@settings(max_examples=30)
@given(st.integers(0, 2**31 - 1), st.sampled_from([0.004, 0.02]))
def test_random_calibrations_along_random_paths(baseline, libdir, seed, period):
    cal = random_calibration(baseline, seed)
    counts = random_path(seed, 400, 1365)
    assert worst_pct(baseline, cal, counts, period, libdir) < TOLERANCE_PCT


@settings(max_examples=15)
@given(st.integers(0, 2**31 - 1), st.sampled_from([0.004, 0.02]), st.booleans())
def test_after_gaps_the_step_is_no_speed_in_both(baseline, libdir, seed, period,
                                                            curved):
    """Samples lost before a sample (failed reads, missed periods): the C++ model told of the
    gaps agrees with the Python one told the periods."""
    cal = random_calibration(baseline, seed)
    cal = with_curves(cal, seed % 7) if curved else cal
    rng = np.random.default_rng(seed)
    counts = random_path(seed, 400, 1365)
    periods = np.where(rng.random(400) < 0.1, rng.integers(2, 300, 400), 1)
    native = native_calibrated(baseline, cal, period, libdir)
    c_wrench, status = native.run(counts, periods)
    py, _ = CalibratedModel(baseline, cal).run(counts, period, periods=periods)
    assert np.all(status == 0)
    assert float((np.abs(c_wrench - py) / full_scale(baseline) * 100).max()) < TOLERANCE_PCT


def test_a_gap_is_not_read_as_one_periods_step(baseline):
    """After lost periods the step is no speed: the speed decays as if the joint stood still
    (read as one period's step, the 40 counts over 20 lost periods were a spike)."""
    cal = random_calibration(baseline, 1).with_(speed_lead_s=0.0)    # the filtered speed
    model = CalibratedModel(baseline, cal)
    counts = np.zeros((12, 6))
    counts[:, 0] = np.r_[np.arange(10) * 2, 58, 60]      # 2 counts a period, then a gap
    periods = np.r_[np.ones(10), 20, 1]
    terms, _ = model.joint_terms(counts, 0.004, periods=periods)
    v = terms.speed[:, 0]
    a = cal.speed_filter_s / (cal.speed_filter_s + 0.004)
    assert v[10] == pytest.approx(a * v[9], rel=1e-12) and v[11] > v[10]
    spike, _ = model.joint_terms(counts, 0.004)
    assert spike.speed[10, 0] > 3 * v[9]


def test_over_the_joint_box_corners_and_faces(baseline, libdir):
    cal = random_calibration(baseline, 7)
    grid = np.array(np.meshgrid(*[[-1365, 0, 1365]] * 6)).reshape(6, -1).T
    # Every pose as a fresh start (settled history) and in one long sequence.
    for i in range(0, len(grid), 81):
        assert worst_pct(baseline, cal, grid[i:i + 81], 0.004, libdir) < TOLERANCE_PCT


def test_along_a_recorded_twin_trajectory(baseline, libdir):
    run = twin.simulate(baseline, twin.scenario_effects("paper", 1), duration_s=20,
                        rate_hz=250, seed=9)
    counts = counts_from_angles(run.theta)
    for seed in (1, 2):
        assert worst_pct(baseline, random_calibration(baseline, seed), counts, 0.004,
                         libdir) < TOLERANCE_PCT


def test_the_generated_header_holds_the_same_constants(baseline, libdir):
    cal = random_calibration(baseline, 11)
    counts = random_path(11, 300, 1365)
    native = native_calibrated(baseline, cal, 0.004, libdir, generated=True)
    assert native.lib.d6c_generated_hash() == cal.hash32()
    from_header, _ = native.run(counts)
    at_run_time, _ = native_calibrated(baseline, cal, 0.004, libdir).run(counts)
    np.testing.assert_array_equal(from_header, at_run_time)


@settings(max_examples=10)
@given(st.integers(0, 2**31 - 1), st.sampled_from([(True, False), (False, True), (True, True)]))
def test_calibrations_with_curves_along_random_paths(baseline, libdir, seed, which):
    cal = with_curves(random_calibration(baseline, seed), seed, *which)
    counts = random_path(seed, 400, 1365)
    assert worst_pct(baseline, cal, counts, 0.004, libdir) < TOLERANCE_PCT


def test_curves_over_the_joint_box_and_along_a_twin_trajectory(baseline, libdir):
    """Both curves at once: every knot interval of every joint (a sweep of the box, each
    joint out of phase with the others), the box's corners, and a recorded trajectory. The
    curves matter far beyond the tolerance (the same calibration without them differs)."""
    base = random_calibration(baseline, 21)
    cal = with_curves(base, 21)
    n = 1365
    sweep = np.stack([np.roll(np.arange(-n, n + 1, 3), 150 * j) for j in range(6)], axis=1)
    grid = np.array(np.meshgrid(*[[-n, 0, n]] * 6)).reshape(6, -1).T
    run = twin.simulate(baseline, twin.scenario_effects("paper", 1), duration_s=10,
                        rate_hz=250, seed=12)
    for counts in (sweep, grid, counts_from_angles(run.theta)):
        assert worst_pct(baseline, cal, counts, 0.004, libdir) < TOLERANCE_PCT
    fs = full_scale(baseline)
    with_, _ = CalibratedModel(baseline, cal).run(sweep, 0.004)
    without, _ = CalibratedModel(baseline, base).run(sweep, 0.004)
    assert (np.abs(with_ - without) / fs * 100).max() > 100 * TOLERANCE_PCT


def test_the_largest_backlash_with_curves_fits_the_fixed_point_angle(baseline, libdir):
    """The curved solve sums the backlash angle and the encoder error between the knots in
    int32 units of 2^-31 rad: the file's largest backlash (0.2 rad) fits with room to spare;
    a backlash at the top of what codegen takes on the gimbal (its first-order turn,
    MAX_GIMBAL_PLAY_RAD) over the widest direction play agrees with Python, reversals
    included."""
    from delta6_codegen.calibration_header import MAX_GIMBAL_PLAY_RAD
    curved = with_curves(random_calibration(baseline, 23), 23)
    widest = curve_constants(baseline, curved.with_(backlash_play_rad=np.full(6, 0.2)))
    assert widest.eh == (round(0.1 * 2 ** 31),) * 6 and max(widest.eh) < 2 ** 30
    cal = curved.with_(backlash_play_rad=np.full(6, MAX_GIMBAL_PLAY_RAD),
                       direction_half_counts=64)
    cv = curve_constants(baseline, cal)
    assert cv.ed == (round(MAX_GIMBAL_PLAY_RAD / 2 / 64 * 2 ** 31),) * 6
    counts = random_path(23, 400, 1365)
    assert worst_pct(baseline, cal, counts, 0.004, libdir) < TOLERANCE_PCT


@pytest.mark.parametrize("which", [(True, False), (False, True), (True, True)])
def test_the_generated_header_holds_the_same_curves(baseline, libdir, which):
    cal = with_curves(random_calibration(baseline, 13), 13, *which)
    counts = random_path(13, 300, 1365)
    native = native_calibrated(baseline, cal, 0.004, libdir, generated=True)
    assert native.curved and native.lib.d6c_generated_hash() == cal.hash32()
    from_header, _ = native.run(counts)
    at_run_time, _ = native_calibrated(baseline, cal, 0.004, libdir).run(counts)
    np.testing.assert_array_equal(from_header, at_run_time)


@pytest.mark.parametrize("curved", [False, True])
def test_outside_the_box_gives_zeros_and_a_status_never_nan(baseline, libdir, curved):
    cal = random_calibration(baseline, 3)
    cal = with_curves(cal, 3) if curved else cal
    native = native_calibrated(baseline, cal, 0.004, libdir)
    rng = np.random.default_rng(0)
    counts = rng.integers(-8192, 8192, size=(2000, 6))
    wrench, status = native.run(counts)
    outside = np.any(np.abs(counts) > 1365, axis=1)
    assert np.all(status[outside] == 1) and np.all(wrench[outside] == 0.0)
    assert np.all(np.isfinite(wrench))


UB_SWEEP = """
import sys
from pathlib import Path
import numpy as np
from delta6.core.design import load
from delta6.core.paths import DEFAULT_DESIGN
from delta6.build.nativecalibrated import native_calibrated
from support.calibrations import random_calibration, with_curves
design = load(DEFAULT_DESIGN)
design = design.replace(k_nm_per_rad=[k * 5 for k in design.k_nm_per_rad])
native = native_calibrated(design, with_curves(random_calibration(design, 3), 3), 0.004,
                           Path(sys.argv[1]), flags=("-fsanitize=undefined",))
x = np.repeat(np.arange(-8192, 8192)[:, None], 6, axis=1)
native.run(np.concatenate([x, x[::-1]]))
print("swept")
"""


def test_no_undefined_behaviour_over_the_whole_turn(tmp_path):
    """Built with UBSan, the curved model of a design with five times the springs (which codegen
    accepts) swept over every count of the turn, in and far out of the box: the int32 torque
    sum overflowed (signed: undefined) on counts outside the box before the box check."""
    import subprocess
    import sys
    from pathlib import Path
    tests = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, "-c", UB_SWEEP, str(tmp_path)],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(tests)})
    assert proc.returncode == 0 and "swept" in proc.stdout, proc.stderr[-2000:]
    assert "runtime error" not in proc.stderr, proc.stderr[-2000:]


def test_torques_beyond_the_fixed_point_range_are_refused(baseline):
    # Within the file's bounds the int32 sums hold the shipped designs (a few 0.1 N*m); a
    # design with springs 30 times stiffer does not fit, and codegen says so.
    calibration_constants(baseline, C.neutral(baseline).with_(hysteresis_nm=np.full((6, 3), 0.5)))
    stiff = baseline.replace(k_nm_per_rad=[20.0] * 6)
    # The line names the cause: the design's own spring span, not the calibration's terms.
    with pytest.raises(CalibrationRangeError, match=r"joint 1's torque sum can reach .* "
                       r"\(the design's spring over its joint box alone: the spring 10\.5 "
                       r"N\*m\), beyond the calibrated firmware's fixed-point range of 8 N\*m"):
        calibration_constants(stiff, C.neutral(stiff))


@pytest.mark.parametrize("spring,encoder", [(False, False), (True, False), (False, True),
                                            (True, True)])
def test_the_header_holds_curve_tables_only_for_the_curves_present(baseline, spring, encoder):
    from delta6_codegen import render_calibration
    cal = random_calibration(baseline, 17)
    if spring or encoder:
        cal = with_curves(cal, 17, spring, encoder)
    text = render_calibration(baseline, cal, "d.toml", "c.toml")
    assert ("kCurveTorque1" in text) == (spring or encoder)
    assert ("CurvedCalibrationConstants" in text) == (spring or encoder)
    assert ("kCurveAngle1" in text) == encoder
    if not (spring or encoder):
        assert "const CalibrationConstants kCalibrationConstants DELTA6_FLASH" in text


@pytest.mark.parametrize("seed", [0, 2, 5, 8])
def test_gimbal_play_beyond_the_boards_first_order_turn_is_refused(baseline, libdir, seed):
    """The gimbal joints' backlash turns their angle to first order on the board: at the
    largest play codegen takes it agrees with Python within the tolerance (with and without
    curves, every joint at the limit); beyond it the disagreement grows with the square of
    the play and codegen refuses the file in one line."""
    from delta6_codegen.calibration_header import MAX_GIMBAL_PLAY_RAD
    counts = random_path(seed, 400, 1365)
    base = random_calibration(baseline, seed)
    for cal in (base, with_curves(base, seed)):
        at_limit = cal.with_(backlash_play_rad=np.full(6, MAX_GIMBAL_PLAY_RAD))
        assert worst_pct(baseline, at_limit, counts, 0.004, libdir) < TOLERANCE_PCT
    play = np.full(6, MAX_GIMBAL_PLAY_RAD)
    play[4] *= 1.5
    with pytest.raises(CalibrationRangeError, match="joint 5's backlash"):
        calibration_constants(baseline, base.with_(backlash_play_rad=play))
    from delta6.core.errors import UserError
    assert issubclass(CalibrationRangeError, UserError)      # one line on the command line


def test_the_fit_holds_gimbal_plays_at_the_boards_limit(baseline):
    """The calibration's backlash family keeps the gimbal plays within the board's limit (the
    bounded fit holds them there) and leaves the branches' free."""
    from delta6.calibration.families import families
    from delta6_codegen.calibration_header import MAX_GIMBAL_PLAY_RAD
    family = families(C.neutral(baseline))["backlash"]
    a, lower = family.constraints(C.neutral(baseline))
    inside = np.array([0.05, -0.05, 0.04, MAX_GIMBAL_PLAY_RAD, -MAX_GIMBAL_PLAY_RAD, 0.0])
    outside = inside.copy()
    outside[5] = 1.01 * MAX_GIMBAL_PLAY_RAD
    assert np.all(a @ inside >= lower - 1e-15)
    assert not np.all(a @ outside >= lower)
