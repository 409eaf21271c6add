"""The harness's second pass in a mix: its clamp and its cable are sought in what the other
families leave, not in the whole residual (which is mostly theirs)."""
from __future__ import annotations

import numpy as np
import pytest

from delta6 import twin
from delta6.diagnosis import run as run_mod
from delta6.diagnosis import selection, stream
from delta6.diagnosis import terms as family
from delta6.diagnosis.data import GapData
from delta6.link.logfile import LogData


def _problem(design, effects, seed, names):
    r = twin.simulate(design, effects, duration_s=120.0, rate_hz=50.0, seed=seed,
                      record_temp=True)
    data = GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c),
                            design)
    problem = selection.build_problem(data, [t for t in family.TERMS if t.name in names])
    return data, problem


def _kept(names) -> run_mod.Selected:
    """A first pass that kept ``names`` (only its families are read here)."""
    return run_mod.Selected([], {}, list(names), {}, {}, {})


@pytest.mark.parametrize("seed", [0])
def test_the_clamp_is_read_with_the_gimbal_springs_fitted(baseline, seed):
    """A linear harness clamped 20 mm off the centre beside a spring-rate error: alone, the
    harness's tilt terms take the gimbal springs' torque (growing with the tilt like a clamp's
    pull) and the clamp came out 4 to 7 mm off the centre; fitted with the spring rates, it
    is where the cable is clamped."""
    harness = twin.make_effect("harness", seed=300 + seed, formulation="linear",
                               magnitude=0.75, attach_offset_mm=20.0)
    springs = twin.make_effect("stiffness_mismatch", seed=310 + seed, magnitude=0.9)
    _, problem = _problem(baseline, [harness, springs], 320 + seed,
                          ("harness", "stiffness_mismatch"))
    alone = family.harness_clamp(run_mod.harness_affine(problem, _kept(["harness"])))
    joint = family.harness_clamp(run_mod.harness_affine(
        problem, _kept(["stiffness_mismatch", "harness"])))
    assert np.linalg.norm(alone - [20.0, 0.0, 0.0]) > 10.0        # why the mix needs it
    assert np.linalg.norm(joint - [20.0, 0.0, 0.0]) < 5.0


@pytest.mark.parametrize("seed", [2])
def test_the_cable_is_sought_in_what_the_other_families_leave(baseline, seed):
    """A slack cable beside a large spring hysteresis: in the whole residual the best single
    cable pulled 10 to 120 degrees off the true one; in the residual less the hysteresis
    (fitted with the harness family, so that it does not take the cable's part) it is
    within a few degrees."""
    harness = twin.make_effect("harness", seed=400 + seed, formulation="cable",
                               magnitude=0.75, attach_offset_mm=0.0)
    pull = harness.p("direction") / np.linalg.norm(harness.p("direction"))
    hysteresis = twin.make_effect("spring_hysteresis", seed=410 + seed, magnitude=0.9)
    data, problem = _problem(baseline, [harness, hysteresis], 420 + seed,
                             ("harness", "spring_hysteresis"))
    target = run_mod.harness_target(data, problem, _kept(["spring_hysteresis", "harness"]))
    assert target.shape == (len(data.t[family.search_rows(len(data))]), 6)
    raw, _, _ = family.cable_search(data)
    found, slack, share = family.cable_search(data, target=target)
    assert np.degrees(np.arccos(raw @ pull)) > 10.0               # why the mix needs it
    assert np.degrees(np.arccos(found @ pull)) < 8.0
    assert 0.0 <= slack <= 6.5 and share > 0.5
    # Nothing else kept: the residual itself, as before.
    assert run_mod.harness_target(data, problem, _kept(["harness"])) is None


def test_a_long_log_reads_the_search_rows_from_its_column_cache(baseline, tmp_path):
    """A long log keeps its columns on disk, not in memory: the search's rows read from the
    cache give the same target (to float32), and without a cache there is none."""
    harness = twin.make_effect("harness", seed=402, formulation="cable", magnitude=0.75)
    hysteresis = twin.make_effect("spring_hysteresis", seed=412, magnitude=0.9)
    data, in_memory = _problem(baseline, [harness, hysteresis], 422,
                               ("harness", "spring_hysteresis"))
    terms = [t for t in family.TERMS if t.name in ("harness", "spring_hysteresis")]
    cache = stream.ColumnCache(tmp_path, sum(len(t.param_names) for t in terms))
    on_disk = selection.build_problem(data, terms, keep_columns=False, cache=cache,
                                      piece_samples=1000)
    kept = _kept(["spring_hysteresis", "harness"])
    want = run_mod.harness_target(data, in_memory, kept)
    got = run_mod.harness_target(data, on_disk, kept, cache)
    assert np.abs(got - want).max() < 1e-6 * np.abs(want).max()
    assert run_mod.harness_target(data, on_disk, kept) is None


def test_the_second_pass_picks_the_cable_sought_beside_the_other_families(baseline):
    """The whole second pass on the cable-beside-hysteresis mix: of its candidates (the cable
    in the whole residual, the cable in what the hysteresis leaves), the one explaining most
    with the hysteresis stands, and its pull is the cable's."""
    harness = twin.make_effect("harness", seed=402, formulation="cable", magnitude=0.75,
                               attach_offset_mm=0.0)
    pull = harness.p("direction") / np.linalg.norm(harness.p("direction"))
    hysteresis = twin.make_effect("spring_hysteresis", seed=412, magnitude=0.9)
    data, problem = _problem(baseline, [harness, hysteresis], 422,
                             ("harness", "spring_hysteresis"))
    terms = [t for t in family.TERMS if t.name in ("harness", "spring_hysteresis")]
    found, _, cable, first = run_mod.harness_second_pass(
        data, problem, terms, seed=0, min_gain=selection.MIN_GAIN,
        confidence=selection.CONFIDENCE, min_share=selection.MIN_SHARE)
    assert "harness" in first.kept and "spring_hysteresis" in first.kept
    assert found is not None and found.name == "harness"
    direction, _ = cable
    assert np.degrees(np.arccos(np.clip(np.asarray(direction) @ pull, -1, 1))) < 8.0
