"""The firmware solver, compiled natively against each design's generated header, against the
Python reference model: over the joint box, at its edges, outside it, and on fuzzed input."""
from __future__ import annotations

import ctypes
import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from delta6.build.nativesolver import CConstants, c_constants, native_solver
from delta6.core.design import load
from delta6.core.model import ENCODER_COUNT_RAD, wrench
from delta6.core.spec import full_scale
from delta6.sim.solverbench import REQUIRED_ACCURACY_PCT_FS
from delta6_codegen import solver_constants

from conftest import DESIGN_FILES, ROOT

OK, OUT_OF_BOX = 0, 1
#: The required accuracy of the native solver, as a fraction of full scale per axis.
REQUIRED_TOLERANCE_FS = REQUIRED_ACCURACY_PCT_FS / 100
#: What float32 reaches (worst seen ~5e-7 FS), with margin: catches a regression that the
#: required tolerance would let through (a coarser table, a dropped term).
FLOAT32_TOLERANCE_FS = 2e-6


def test_the_required_accuracy_is_the_documented_one_everywhere():
    """docs/firmware.md states the requirement; the AVR benchmark gated at 0.05 % FS while
    the docs and these tests said 0.01: every gate now reads the one constant."""
    doc = (ROOT / "docs" / "firmware.md").read_text()
    said = re.search(r"The required tolerance is ([0-9.]+) % FS", doc)[1]
    assert float(said) == REQUIRED_ACCURACY_PCT_FS
    bench = (ROOT / "tools" / "bench_solver_avr.py").read_text()
    assert "REQUIRED_ACCURACY_PCT_FS = solverbench.REQUIRED_ACCURACY_PCT_FS" in bench
    assert not re.search(r"\b0\.0[15]\b", bench)     # no second copy of the figure


@pytest.fixture(scope="session")
def solvers(tmp_path_factory):
    """design name -> (design, native solver built from its generated header, full scale)."""
    base = tmp_path_factory.mktemp("headers")
    out = {}
    for path in DESIGN_FILES:
        d = load(path)
        out[path.stem] = (d, native_solver(d, base, f"designs/{path.name}"), full_scale(d))
    return out


@pytest.fixture(scope="session", params=[p.stem for p in DESIGN_FILES])
def case(request, solvers):
    return solvers[request.param]


def limits(design):
    sc = solver_constants(design)
    return sc.limit_counts, sc.limit_rad


def worst_error_fs(native, ref, fs):
    return (np.abs(native.astype(float) - ref) / fs).max(axis=0)


def test_header_values_match_python(case):
    d, solver, fs = case
    lim_counts, lim_rad = limits(d)
    assert solver.design_name() == d.name
    assert solver.lib.d6_design_hash() == d.hash32()
    np.testing.assert_array_equal(solver.design_full_scale(), fs.astype(np.float32))
    assert solver.lib.d6_design_limit_counts() == lim_counts
    assert solver.lib.d6_design_limit_rad() == np.float32(lim_rad)
    assert solver.lib.d6_constants_size() == ctypes.sizeof(CConstants)


def corner_and_edge_counts(limit: int) -> np.ndarray:
    corners = np.array([[limit if (i >> j) & 1 else -limit for j in range(6)] for i in range(64)])
    rng = np.random.default_rng(7)
    edges = rng.integers(-limit, limit + 1, size=(600, 6))
    for n, row in enumerate(edges):
        row[n % 6] = (limit, -limit, limit - 1, -limit + 1, 0)[n % 5]
    return np.concatenate([corners, edges, np.zeros((1, 6), dtype=int)])


def test_sweep_over_the_box_within_tolerance(case):
    d, solver, fs = case
    lim, _ = limits(d)
    rng = np.random.default_rng(2024)
    counts = np.concatenate([corner_and_edge_counts(lim),
                             rng.integers(-lim, lim + 1, size=(20000, 6))]).astype(np.int16)
    w, status = solver.solve_counts(counts)
    assert (status == OK).all()
    err = worst_error_fs(w, wrench(d, counts * ENCODER_COUNT_RAD), fs)
    assert (err < REQUIRED_TOLERANCE_FS).all(), err
    assert (err < FLOAT32_TOLERANCE_FS).all(), err


def test_rest_gives_exactly_zero(case):
    _, solver, _ = case
    w, status = solver.solve_counts(np.zeros((1, 6)))
    assert status[0] == OK
    assert (w == 0).all()


@given(data=st.data())
def test_counts_match_reference(case, data):
    d, solver, fs = case
    lim, _ = limits(d)
    counts = np.array(data.draw(st.lists(st.integers(-lim, lim), min_size=6, max_size=6)))
    w, status = solver.solve_counts(counts)
    assert status[0] == OK
    err = worst_error_fs(w, wrench(d, counts[None] * ENCODER_COUNT_RAD), fs)
    assert (err < FLOAT32_TOLERANCE_FS).all(), err


@given(data=st.data())
def test_radians_match_reference(case, data):
    d, solver, fs = case
    _, lim = limits(d)
    angle = st.floats(-lim, lim, width=32, allow_subnormal=False)
    theta = np.array(data.draw(st.lists(angle, min_size=6, max_size=6)), dtype=np.float32)
    w, status = solver.solve_radians(theta)
    assert status[0] == OK
    err = worst_error_fs(w, wrench(d, theta.astype(float)[None]), fs)
    assert (err < FLOAT32_TOLERANCE_FS).all(), err


def test_box_edges_are_exact(case):
    """The last count and the last float inside the box solve; the next ones are refused."""
    d, solver, fs = case
    lim, lim_rad = limits(d)
    assert lim * ENCODER_COUNT_RAD <= d.joint_limit_rad < (lim + 1) * ENCODER_COUNT_RAD
    assert lim_rad <= d.joint_limit_rad < float(np.nextafter(np.float32(lim_rad), np.float32(9)))
    for j in range(6):
        for sign in (1, -1):
            inside = np.zeros(6, dtype=int)
            inside[j] = sign * lim
            outside = inside.copy()
            outside[j] = sign * (lim + 1)
            w, status = solver.solve_counts(np.stack([inside, outside]))
            assert list(status) == [OK, OUT_OF_BOX]
            assert (w[1] == 0).all()
            ref = wrench(d, inside * ENCODER_COUNT_RAD)
            assert (np.abs(w[0] - ref) / fs < FLOAT32_TOLERANCE_FS).all()

            edge = np.zeros(6, dtype=np.float32)
            edge[j] = sign * np.float32(lim_rad)
            past = edge.copy()
            past[j] = np.nextafter(edge[j], np.float32(sign * 9))
            w, status = solver.solve_radians(np.stack([edge, past]))
            assert list(status) == [OK, OUT_OF_BOX]
            assert (w[1] == 0).all()


@given(data=st.data())
def test_outside_the_box_is_refused_with_zeros(case, data):
    d, solver, _ = case
    lim, _ = limits(d)
    counts = data.draw(st.lists(st.integers(-lim, lim), min_size=6, max_size=6))
    bad = data.draw(st.integers(0, 5))
    counts[bad] = data.draw(st.one_of(st.integers(lim + 1, 8191), st.integers(-8192, -lim - 1)))
    w, status = solver.solve_counts(np.array(counts))
    assert status[0] == OUT_OF_BOX
    assert (w == 0).all() and not np.signbit(w).any()


@given(counts=st.lists(st.integers(-32768, 32767), min_size=6, max_size=6))
def test_fuzzed_counts_never_give_nonfinite_output(case, counts):
    d, solver, fs = case
    lim, _ = limits(d)
    w, status = solver.solve_counts(np.array(counts))
    assert np.isfinite(w).all()
    inside = max(abs(c) for c in counts) <= lim
    assert status[0] == (OK if inside else OUT_OF_BOX)
    if inside:
        err = worst_error_fs(w, wrench(d, np.array(counts)[None] * ENCODER_COUNT_RAD), fs)
        assert (err < FLOAT32_TOLERANCE_FS).all()
    else:
        assert (w == 0).all()


@given(bits=st.lists(st.integers(0, 2**32 - 1), min_size=6, max_size=6))
def test_fuzzed_float_bits_never_give_nonfinite_output(case, bits):
    """Any 32-bit pattern, NaN and infinities included."""
    d, solver, _ = case
    _, lim_rad = limits(d)
    theta = np.array(bits, dtype=np.uint32).view(np.float32)
    w, status = solver.solve_radians(theta)
    assert np.isfinite(w).all()
    with np.errstate(invalid="ignore"):
        inside = bool((np.abs(theta) <= np.float32(lim_rad)).all())
    assert status[0] == (OK if inside else OUT_OF_BOX)
    if not inside:
        assert (w == 0).all()


def test_special_float_inputs_are_refused(case):
    _, solver, _ = case
    for bad in (np.nan, np.inf, -np.inf):
        theta = np.zeros(6, dtype=np.float32)
        theta[3] = bad
        w, status = solver.solve_radians(theta)
        assert status[0] == OUT_OF_BOX and (w == 0).all()


# --- the trig tables, exhaustively ---------------------------------------------------------

#: Error bound of the table angle addition relative to the table's amplitude (la or 1): a
#: few float32 roundings (2^-24 = 6e-8 each). Proven by the exhaustive test below.
TABLE_ERROR_BOUND = 3e-7


def test_table_trig_exhaustive_over_every_count(case):
    """Every encoder count of the joint box, both tables: the proven error bound."""
    d, solver, _ = case
    lim, _ = limits(d)
    counts = np.arange(-lim, lim + 1)
    q = counts * ENCODER_COUNT_RAD
    la = d.la_mm * 1e-3
    c, s = solver.table_trig(counts, branch=True)
    assert np.abs(c - la * np.cos(d.theta_offset_rad + q)).max() <= TABLE_ERROR_BOUND * la
    assert np.abs(s - la * np.sin(d.theta_offset_rad + q)).max() <= TABLE_ERROR_BOUND * la
    c, s = solver.table_trig(counts, branch=False)
    assert np.abs(c - np.cos(q)).max() <= TABLE_ERROR_BOUND
    assert np.abs(s - np.sin(q)).max() <= TABLE_ERROR_BOUND


def test_table_indices_stay_inside_the_tables(case):
    d, _, _ = case
    sc = solver_constants(d)
    assert sc.table_origin % 64 == 0 and sc.table_origin >= sc.limit_counts
    assert (sc.table_origin + sc.limit_counts) // 64 < len(sc.branch_table)
    assert len(sc.branch_table) == len(sc.joint_table) and len(sc.fine_table) == 64


def test_wrap_count_delta(solvers):
    _, solver, _ = solvers["delta6"]
    for zero in (0, 1, 8191, 8192, 16383, 5000):
        for raw in range(0, 16384, 7):
            expected = (raw - zero + 8192) % 16384 - 8192
            assert solver.wrap_count_delta(raw, zero) == expected


# --- constants given at run time: other designs and the fault thresholds -------------------

def test_runtime_constants_match_the_generated_header(case):
    d, solver, _ = case
    lim, _ = limits(d)
    counts = np.random.default_rng(3).integers(-lim, lim + 1, size=(500, 6))
    np.testing.assert_array_equal(solver.solve_counts(counts)[0],
                                  solver.solve_counts(counts, c_constants(solver_constants(d)))[0])


@settings(max_examples=12)
@given(a=st.floats(60, 90), b=st.floats(10, 30), la=st.floats(25, 55), lb=st.floats(100, 160),
       off=st.floats(0.2, 0.8), k=st.lists(st.floats(0.2, 2.0), min_size=6, max_size=6))
def test_random_designs_with_runtime_constants(solvers, a, b, la, lb, off, k):
    """Designs nobody generated a header for, through the same compiled solver."""
    from delta6.core.design import DesignError
    from delta6.core.workspace import check_solvable
    _, solver, _ = solvers["delta6"]
    try:
        d = solvers["delta6"][0].replace(a_mm=a, b_mm=b, la_mm=la, lb_mm=lb,
                                         theta_offset_rad=off, k_nm_per_rad=k)
        check_solvable(d)
        sc = solver_constants(d)
    except DesignError:
        assume(False)
    counts = np.random.default_rng(5).integers(-sc.limit_counts, sc.limit_counts + 1, (400, 6))
    w, status = solver.solve_counts(counts, c_constants(sc))
    ref = wrench(d, counts * ENCODER_COUNT_RAD)
    assert (status == OK).all()
    scale = np.abs(ref).max(axis=0)      # below the design's full scale: a stricter test
    assert (worst_error_fs(w, ref, scale) < FLOAT32_TOLERANCE_FS * 3).all()
