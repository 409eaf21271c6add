"""Whole runs: the ideal floor and the paper band, determinism, the truth file, the log."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6 import twin
from delta6.core import model
from delta6.core.errors import UserError
from delta6.link.logfile import read_log

from support.twinkit import CLEAN


def run(design, effects=(), seed=1, duration=30.0, **kw):
    return twin.simulate(design, effects, duration_s=duration, seed=seed, **kw)


def test_ideal_plant_sits_at_the_noise_and_quantization_floor(baseline):
    result = run(baseline, duration=600, seed=4)
    p99 = np.array(result.gap((99,))["p99"])
    assert np.all(p99 < 0.5), p99
    assert np.all(p99 > 0.05)    # the floor is noise, not zero
    # Without the reference noise only the 14-bit quantization is left: far below.
    quiet = run(baseline, duration=600, seed=4,
                measurement=twin.Measurement(force_noise_n=0, moment_noise_nm=0))
    assert np.all(np.array(quiet.gap((99,))["p99"]) < 0.1)


@pytest.mark.parametrize("seed", [1, 7])
def test_paper_scenario_reproduces_table_v_band(baseline, seed):
    """The paper's run length (2000 s, 10^5 samples): p99 in 3.5..7.5 % FS on every axis."""
    result = run(baseline, twin.scenario_effects("paper", seed), seed=seed, duration=2000)
    p99 = np.array(result.gap((99,))["p99"])
    assert len(result) == 100_000
    assert np.all((3.5 <= p99) & (p99 <= 7.5)), p99


def test_runs_are_deterministic_for_a_seed(baseline):
    effects = twin.scenario_effects("paper", 3)
    a, b = run(baseline, effects, seed=3), run(baseline, twin.scenario_effects("paper", 3), seed=3)
    for key in ("t", "theta", "wrench", "true_angles", "true_wrench"):
        assert np.array_equal(getattr(a, key), getattr(b, key))
    strip = lambda t: {k: v for k, v in t.items() if k != "generation_s"}
    assert strip(a.truth) == strip(b.truth)
    c = run(baseline, effects, seed=4)
    assert not np.array_equal(a.theta, c.theta)


def test_effects_do_not_disturb_each_others_random_streams(baseline):
    plain = run(baseline, seed=6)
    shifted = run(baseline, [twin.make_effect("encoder_offset", 6)], seed=6)
    assert np.array_equal(plain.true_angles, shifted.true_angles)
    assert np.array_equal(plain.wrench, shifted.wrench)      # same plant, same noise
    assert not np.array_equal(plain.theta, shifted.theta)


def test_wrench_at_the_logged_rows_equals_the_fine_grid_one(baseline):
    """Without a TIME effect the statics runs on the logged rows only; a zero transport delay
    makes the plant compute it on every step instead: the same numbers."""
    rows = run(baseline, [twin.make_effect("link_compliance", 8)], seed=8)
    fine = run(baseline, [twin.make_effect("link_compliance", 8),
                          twin.make_effect("sensor_latency", 8, latency_s=0.0)], seed=8)
    assert np.array_equal(rows.true_wrench, fine.true_wrench)
    assert np.array_equal(rows.wrench, fine.wrench)


def test_model_wrench_is_the_model_on_the_logged_angles_computed_once(baseline):
    result = run(baseline, duration=5)
    assert np.array_equal(result.model_wrench(), model.wrench(baseline, result.theta))
    assert result.model_wrench() is result.model_wrench()
    assert not result.model_wrench().flags.writeable


def test_truth_reproduces_the_run_exactly(baseline, tmp_path):
    effects = [twin.random_effect(n, 21) for n in twin.EFFECT_NAMES]
    result = run(baseline, effects, seed=21, duration=20, scenario="everything")
    csv, truth_file = twin.write_log(result, tmp_path / "data.csv")
    assert truth_file == tmp_path / "data.truth.json" == twin.truth_path(csv)
    truth = twin.read_truth(truth_file)
    again = twin.simulate(**twin.replay_arguments(truth))
    assert np.array_equal(again.theta, result.theta)
    assert np.array_equal(again.wrench, result.wrench)
    assert np.array_equal(again.temp_c, result.temp_c)
    # Drawn values are recorded exactly (JSON floats round-trip).
    for e, rec in zip(effects, truth["effects"]):
        assert rec["name"] == e.NAME and rec["formulation"] == e.formulation
        for k, v in e.params.items():
            assert np.array_equal(np.asarray(rec["parameters"][k]).reshape(v.shape), v)


small = st.floats(-1.0, 1.0, allow_nan=False)


@given(st.booleans(), st.integers(4, 24), st.floats(0, 1), st.floats(0, 1),
       st.tuples(small, small, small), st.tuples(small, small, small))
def test_measurement_settings_round_trip_through_the_truth_record(quantize, bits, force, moment,
                                                                  turn, offset):
    m = twin.Measurement(quantize=quantize, encoder_bits=bits, force_noise_n=force,
                         moment_noise_nm=moment, sensor_turn_rad=turn, sensor_offset_m=offset)
    assert twin.Measurement.from_dict(json.loads(json.dumps(m.as_dict()))) == m


def test_truth_holds_the_run_effects_and_their_parameters(baseline):
    result = run(baseline, twin.scenario_effects("paper", 2), seed=2, duration=10,
                 scenario="paper")
    t = result.truth
    json.dumps(t)   # serialisable as is
    assert t["schema"] == "delta6-twin-truth/1" and t["scenario"] == "paper"
    assert t["design"] == {"name": "delta6", "hash": f"0x{baseline.hash32():08x}",
                           "parameters": baseline.canonical()}
    assert (t["seed"], t["duration_s"], t["rate_hz"], t["samples"]) == (2, 10.0, 50.0, 500)
    assert t["trajectory"]["coverage"] == twin.TrajectorySettings().coverage
    assert t["measurement"]["reference_noise"]["force_sd_n"] > 0
    assert t["measurement"]["encoder_bits"] == 14
    names = [e["name"] for e in t["effects"]]
    assert names == [r.name for r in twin.SCENARIOS["paper"]]
    for e in t["effects"]:
        assert {"formulation", "acts_on", "parameters", "units", "summary"} <= set(e)
    assert set(t["analytical_error_pct_fs"]) == {"p50", "p95", "p99", "p100"}


def test_log_file_is_the_documented_format(baseline, tmp_path):
    result = run(baseline, [twin.make_effect("thermal_drift", 1)], duration=12, rate_hz=25)
    csv, _ = twin.write_log(result, tmp_path / "run.csv")
    log = read_log(csv)
    assert log.meta["design"] == "delta6" and log.meta["truth"] == "run.truth.json"
    assert np.allclose(np.diff(log.t), 1 / 25)
    assert np.allclose(log.theta, result.theta, rtol=1e-8, atol=1e-12)
    assert np.allclose(log.wrench, result.wrench, rtol=1e-8, atol=1e-12)
    assert log.temp_c is not None and np.allclose(log.temp_c, result.temp_c, rtol=1e-8)
    # Encoder angles are whole counts of the 14-bit encoders.
    counts = log.theta / model.ENCODER_COUNT_RAD
    assert np.allclose(counts, np.round(counts), atol=1e-6)


def test_temperature_column_can_be_always_present(baseline):
    assert run(baseline).temp_c is None
    with_temp = run(baseline, record_temp=True)
    assert with_temp.temp_c is not None and with_temp.truth["temperature"]["recorded"]
    assert np.ptp(with_temp.temp_c) > 1.0


def test_bad_runs_are_refused(baseline):
    with pytest.raises(ValueError, match="seed"):
        run(baseline, seed=-1)
    with pytest.raises(ValueError, match="rate"):
        run(baseline, rate_hz=0)
    with pytest.raises(ValueError, match="fewer than 2 samples"):
        run(baseline, duration=0.01)
    e = twin.make_effect("backlash", 1)
    with pytest.raises(ValueError, match="once"):
        run(baseline, [e, e])


def test_latency_reaches_back_before_the_log_starts(baseline):
    """The plant runs a settled pre-roll, so the first rows already carry the delay."""
    result = run(baseline, [twin.make_effect("sensor_latency", 1, latency_s=0.04)],
                 measurement=CLEAN, duration=5)
    assert np.all(np.isfinite(result.wrench))
    assert np.allclose(result.wrench[:2], 0.0, atol=1e-12)   # at rest before t = 0


def test_removing_effects_from_a_recorded_run_keeps_everything_else(baseline):
    """The "true shrink" of a diagnosis: the same run without the effects it models."""
    result = run(baseline, twin.scenario_effects("paper", 5), seed=5, duration=20)
    rest = twin.simulate(**twin.without(result.truth, ["backlash", "sensor_latency"]))
    assert [e["name"] for e in rest.truth["effects"]] == [
        r.name for r in twin.SCENARIOS["paper"] if r.name not in ("backlash", "sensor_latency")]
    assert np.array_equal(rest.true_angles, result.true_angles)
    bare = twin.simulate(**twin.without(result.truth, [r.name for r in twin.SCENARIOS["paper"]]))
    ideal = run(baseline, seed=5, duration=20)
    assert np.array_equal(bare.wrench, ideal.wrench) and np.array_equal(bare.theta, ideal.theta)
    with pytest.raises(UserError, match="no effect 'thermal_drift'"):
        twin.without(result.truth, ["thermal_drift"])


def test_registry_is_plain_data():
    info = twin.registry_info()
    json.dumps(info)
    assert info["backlash"]["parameters"]["play_rad"]["unit"] == "rad"
    assert info["thermal_drift"]["acts_on"] == ["torque", "angle"]
