"""The calibration's per-joint curve tables (delta6.core.curves): the interpolated tables follow
the exact curves over the joint box within the bound of linear interpolation plus rounding,
are zero at the rest count, and the calibrated model applies them on the right sides."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.core import calibration as C
from delta6.core import curves
from delta6.core.calibrated import CalibratedModel
from delta6.core.model import ENCODER_COUNT_RAD

H = curves.KNOT_COUNTS * ENCODER_COUNT_RAD          # knot spacing, rad
HARMONICS = np.repeat(curves.ENCODER_HARMONICS, 2).astype(float)   # per coefficient

coefficients = st.integers(0, 2**32 - 1)


def _box(baseline) -> np.ndarray:
    n = curves.limit_counts(baseline)
    return np.linspace(-n, n, 4001).round()[:, None] * np.ones(6)


def _encoder(seed) -> np.ndarray:
    # Realistic magnets: up to 0.015 rad in the first harmonic, falling as 1/h, any phase.
    rng = np.random.default_rng(seed)
    return rng.uniform(-0.015, 0.015, (6, 8)) / HARMONICS


def _spring(seed) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.6, 0.6, (6, 2))


@settings(max_examples=40)
@given(coefficients)
def test_the_encoder_table_follows_the_curve_over_the_box(baseline, seed):
    coef = _encoder(seed)
    cal = C.neutral(baseline).with_(encoder_periodic_rad=coef)
    tables = curves.curve_tables(baseline, cal)
    x = _box(baseline)
    got = curves.interpolate(tables.angle, tables.knots, x) * 2.0 ** -curves.ANGLE_SHIFT
    exact = curves.encoder_error(x * ENCODER_COUNT_RAD, coef)
    # Linear interpolation: h^2 / 8 max|e''|, with |e''| <= sum h^2 |coefficient|; rounding
    # to the table's unit: half a unit.
    bound = H ** 2 / 8 * (np.abs(coef) * HARMONICS ** 2).sum(axis=1) \
        + 0.5 * 2.0 ** -curves.ANGLE_SHIFT
    assert np.all(np.abs(got - exact) <= bound * (1 + 1e-9)), (np.abs(got - exact).max(0), bound)
    # Zero at the rest count, where the encoders are zeroed (a knot).
    assert np.all(tables.angle[:, np.flatnonzero(tables.knots == 0)] == 0)
    assert np.all(curves.interpolate(tables.angle, tables.knots, np.zeros((1, 6))) == 0)


@settings(max_examples=40)
@given(coefficients)
def test_the_spring_table_follows_the_curve_over_the_box(baseline, seed):
    coef = _spring(seed)
    cal = C.neutral(baseline).with_(spring_curvature=coef)
    tables = curves.curve_tables(baseline, cal)
    assert tables.angle is None
    x = _box(baseline)
    q = x * ENCODER_COUNT_RAD
    got = curves.interpolate(tables.torque, tables.knots, x) * 2.0 ** -curves.TORQUE_SHIFT
    exact = curves.spring_torque(q, baseline.k, coef)
    # s'' = k (2 p1 sign(q) / R + 6 p2 q / R^2): bounded over the box by its value at the end.
    r = curves.SPRING_REF_RAD
    q_max = np.abs(q).max()
    bound = H ** 2 / 8 * baseline.k * (2 * np.abs(coef[:, 0]) / r
                                       + 6 * np.abs(coef[:, 1]) * q_max / r ** 2) \
        + 0.5 * 2.0 ** -curves.TORQUE_SHIFT
    assert np.all(np.abs(got - exact) <= bound * (1 + 1e-9))
    assert np.all(curves.interpolate(tables.torque, tables.knots, np.zeros((1, 6))) == 0)


def test_the_torque_table_holds_the_spring_at_the_links_angle_and_the_encoder_errors_torque(
        baseline):
    """The spring bends with the link: its curve at x count - offset - e(x); the encoder
    error's torque through the calibrated rate, - k ratio e(x)."""
    cal = C.neutral(baseline).with_(encoder_periodic_rad=_encoder(3), spring_curvature=_spring(3),
                                    rate_ratio=np.linspace(0.9, 1.1, 6),
                                    offset_rad=np.linspace(-0.01, 0.01, 6))
    t = curves.curve_tables(baseline, cal)
    q = t.knots[:, None] * ENCODER_COUNT_RAD * np.ones(6)
    e = t.angle.T * 2.0 ** -curves.ANGLE_SHIFT
    expected = curves.spring_torque(q - cal.offset_rad - e, baseline.k, cal.spring_curvature) \
        - baseline.k * cal.rate_ratio * e
    np.testing.assert_allclose(t.torque.T * 2.0 ** -curves.TORQUE_SHIFT, expected,
                               atol=0.5 * 2.0 ** -curves.TORQUE_SHIFT)


def test_interpolation_is_exact_at_knots_and_held_outside(baseline):
    cal = C.neutral(baseline).with_(spring_curvature=_spring(5))
    t = curves.curve_tables(baseline, cal)
    at = np.repeat(t.knots[:, None], 6, axis=1)
    np.testing.assert_array_equal(curves.interpolate(t.torque, t.knots, at), t.torque.T)
    far = np.array([[-9000] * 6, [9000] * 6])
    np.testing.assert_array_equal(curves.interpolate(t.torque, t.knots, far),
                                  t.torque[:, [0, -1]].T)
    # The knots are the firmware's coarse-table rows (from its origin), and one beyond the box.
    n = curves.limit_counts(baseline)
    assert t.knots[0] % curves.KNOT_COUNTS == 0 and t.knots[-2] <= n < t.knots[-1]


def test_no_curves_no_tables_and_the_model_is_the_rate_alone(baseline):
    """Without curves the joint's angle is the count angle and its torque the rate's: any
    change to the model without curves shows here."""
    cal = C.neutral(baseline).with_(rate_ratio=np.linspace(0.9, 1.1, 6),
                                    offset_rad=np.linspace(-0.01, 0.01, 6))
    assert curves.curve_tables(baseline, cal) is None and not curves.has_curves(baseline, cal)
    x = _box(baseline)[::50]
    terms, _ = CalibratedModel(baseline, cal).joint_terms(x, 0.02)
    theta = x * ENCODER_COUNT_RAD - cal.offset_rad
    np.testing.assert_array_equal(terms.theta, theta)
    np.testing.assert_allclose(terms.torque, baseline.k * cal.rate_ratio * theta,
                               rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("field,value", [("spring_curvature", 1e-7),
                                         ("encoder_periodic_rad", 1e-9)])
def test_a_curve_that_rounds_to_zero_in_the_tables_is_no_curve(baseline, field, value):
    """A curve is what the board's tables hold: one that rounds to zero at every knot gives no
    tables (so no curved image, no lower rated rate) and the model without it, exactly."""
    shape = np.shape(getattr(C.neutral(baseline), field))
    cal = C.neutral(baseline).with_(**{field: np.full(shape, value)})
    assert curves.curve_tables(baseline, cal) is None and not curves.has_curves(baseline, cal)
    x = _box(baseline)[::50]
    a, _ = CalibratedModel(baseline, cal).run(x, 0.02)
    b, _ = CalibratedModel(baseline, C.neutral(baseline)).run(x, 0.02)
    np.testing.assert_array_equal(a, b)


def test_an_encoder_curve_whose_angle_table_rounds_to_zero_has_no_angle_table(baseline):
    cal = C.neutral(baseline).with_(spring_curvature=_spring(4),
                                    encoder_periodic_rad=np.full((6, 8), 1e-9))
    tables = curves.curve_tables(baseline, cal)
    assert tables.angle is None and np.any(tables.torque)


def test_the_model_applies_the_encoder_error_on_the_angle_side(baseline):
    """theta = x count - e(x): a unit whose encoder reads e ahead gives the analytical wrench
    of the angle behind it."""
    coef = _encoder(8)
    cal = C.neutral(baseline).with_(encoder_periodic_rad=coef)
    x = _box(baseline)[::40]
    terms, _ = CalibratedModel(baseline, cal).joint_terms(x, 0.02)
    e = curves.encoder_error(x * ENCODER_COUNT_RAD, coef)
    np.testing.assert_allclose(terms.theta, x * ENCODER_COUNT_RAD - e, atol=2e-5)
    np.testing.assert_allclose(terms.torque, baseline.k * terms.theta, atol=2e-5)


def test_a_curve_beyond_the_boards_table_is_one_line_or_held_at_the_range(baseline):
    cal = C.neutral(baseline).with_(encoder_periodic_rad=np.full((6, 8), 0.1))
    with pytest.raises(curves.CurveRangeError, match="periodic_rad.*knots"):
        CalibratedModel(baseline, cal)
    # A fit's iterate: held at the table's range, as a board with such a table would be.
    tables = CalibratedModel(baseline, cal, saturate_curves=True).curves
    assert np.abs(tables.angle).max() == curves.INT16_MAX
    assert np.abs(tables.torque).max() <= curves.INT16_MAX
