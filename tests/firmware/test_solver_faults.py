"""The solver's fault flags against the reference model: geometries whose links cannot close,
pass through a singular pose, or degenerate, driven through run-time constants.

The shipped designs never raise these flags inside their box (the design check proves it
with margin and tests/firmware/test_solver_native.py sweeps it); here the thresholds are moved, or the
geometry broken, so that the flags must fire exactly where the reference says they should.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from delta6.build.nativesolver import c_constants, native_solver
from delta6.core.design import load
from delta6.core.model import (
    ENCODER_COUNT_RAD,
    Params,
    branch_centres,
    branch_forces,
    forward_kinematics,
    wrench,
)
from delta6_codegen import solver_constants
from delta6_codegen.solver_constants import f32

from conftest import DESIGNS

OK, OUT_OF_BOX, NO_SOLUTION, SINGULAR = 0, 1, 2, 4
#: Samples this close (relative) to a threshold may fall either way in float32.
AMBIGUOUS = 1e-3
#: Per-sample relative agreement with the reference where no flag is raised; poses near
#: the thresholds are ill-conditioned (the shipped designs stay far from them: ~3e-7).
RELATIVE_TOLERANCE = 1e-4


@pytest.fixture(scope="module")
def solver(tmp_path_factory):
    d = load(DESIGNS / "delta6.toml")
    return native_solver(d, tmp_path_factory.mktemp("faults"), "designs/delta6.toml")


def sample_counts(design, n=6000, seed=11):
    lim = solver_constants(design).limit_counts
    return np.random.default_rng(seed).integers(-lim, lim + 1, size=(n, 6))


def reference_terms(design, counts) -> dict[str, np.ndarray]:
    """The reference quantity behind each threshold, keyed by the SolverConstants field:
    squared trilateration height, min |G_i| = min |lever_i| lb, and S."""
    theta = counts * ENCODER_COUNT_RAD
    p = Params.from_design(design)
    _, height_sq = forward_kinematics(p, theta[:, :3], return_disc=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        _, lever = branch_forces(p, theta[:, :3])
    r = np.hypot(*np.moveaxis(branch_centres(p, theta[:, :3])[..., :2], -1, 0))
    return {
        "min_height_sq": height_sq,
        "min_lever": np.abs(lever).min(axis=1) * design.lb_mm * 1e-3,
        "min_area": r[:, 0] * r[:, 1] + r[:, 1] * r[:, 2] + r[:, 2] * r[:, 0],
    }


def sides(values, threshold):
    """(flagged, clear) masks: clearly below / clearly above a threshold."""
    return values < threshold * (1 - AMBIGUOUS), values > threshold * (1 + AMBIGUOUS)


def check_flag(solver, design, constants, counts, flag, flagged_where, clear_where):
    w, status = solver.solve_counts(counts, c_constants(constants))
    assert np.isfinite(w).all()
    assert (status[flagged_where] == flag).all()
    assert (w[flagged_where] == 0).all()
    assert (status[clear_where] == OK).all()
    ref = wrench(design, counts[clear_where] * ENCODER_COUNT_RAD)
    # Near a singular pose the force grows without bound and float32 rounding grows with it:
    # compare each sample relative to its own force and moment magnitude.
    err = np.abs(w[clear_where] - ref)
    force_scale = np.linalg.norm(ref[:, :3], axis=1, keepdims=True) + 1e-6
    moment_scale = np.linalg.norm(ref[:, 3:], axis=1, keepdims=True) + 1e-9
    rel = np.concatenate([err[:, :3] / force_scale, err[:, 3:] / moment_scale], axis=1)
    assert rel.max() < RELATIVE_TOLERANCE, rel.max()
    return status


def test_links_that_cannot_close_report_no_solution(solver):
    """lb too short for part of the box: the reference has no solution (NaN) there."""
    design = load(DESIGNS / "delta6.toml").replace(lb_mm=85.0)
    sc = solver_constants(design)
    counts = sample_counts(design)
    height_sq = reference_terms(design, counts)["min_height_sq"]
    flagged, clear = sides(height_sq, sc.min_height_sq)
    assert flagged.mean() > 0.2 and clear.mean() > 0.2       # both sides are exercised
    assert np.isnan(wrench(design, counts[height_sq < 0] * ENCODER_COUNT_RAD)[:, :3]).all()
    check_flag(solver, design, sc, counts, NO_SOLUTION, flagged, clear)


def test_singular_pose_reports_singular(solver):
    """An offset that lets a proximal link line up with its parallelogram inside the box."""
    design = load(DESIGNS / "delta6.toml").replace(theta_offset_rad=-0.6)
    sc = solver_constants(design)
    counts = sample_counts(design, n=20000)
    flagged, clear = sides(reference_terms(design, counts)["min_lever"], sc.min_lever)
    assert flagged.sum() > 50
    either = clear | flagged
    status = check_flag(solver, design, sc, counts[either], SINGULAR, flagged[either],
                        clear[either])
    assert (status != OK).sum() == flagged.sum()


@pytest.mark.parametrize("field, flag", [("min_height_sq", NO_SOLUTION),
                                         ("min_lever", SINGULAR), ("min_area", SINGULAR)])
def test_threshold_is_where_the_constant_says(solver, field, flag):
    """Move one threshold to the median of its quantity over the box: half the samples must
    be flagged, exactly those the reference puts below it."""
    design = load(DESIGNS / "delta6.toml")
    counts = sample_counts(design)
    values = reference_terms(design, counts)[field]
    sc = replace(solver_constants(design), **{field: f32(np.median(values))})
    flagged, clear = sides(values, getattr(sc, field))
    check_flag(solver, design, sc, counts, flag, flagged, clear)


def test_shipped_thresholds_never_fire_inside_the_box():
    """The generated thresholds sit well inside what the design check proves."""
    for path in sorted(DESIGNS.glob("*.toml")):
        design = load(path)
        sc = solver_constants(design)
        for field, values in reference_terms(design, sample_counts(design, 20000)).items():
            assert values.min() > 4 * getattr(sc, field), (path.name, field)


def test_codegen_refuses_designs_the_solver_cannot_serve():
    """An elbow centre that can reach the base axis would make the elimination degenerate."""
    from delta6.core.design import DesignError
    design = load(DESIGNS / "delta6.toml").replace(la_mm=200.0, theta_offset_rad=1.5,
                                                   joint_limit_rad=1.5)
    with pytest.raises(DesignError, match="la_mm"):
        solver_constants(design)
