"""Long logs in pieces: the streamed columns equal the whole log's, the streamed percentiles
equal numpy's, the Gram summaries do not depend on how the log is cut, and the column cache
gives back what it was given."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6 import twin
from delta6.diagnosis import selection, stream
from delta6.diagnosis.data import GapData
from delta6.diagnosis.terms import TERMS
from delta6.link.logfile import LogData


@pytest.fixture(scope="module")
def history_log(baseline):
    """A twin run with every history the terms follow (plays, dwells, lags, derivatives)."""
    effects = [twin.make_effect(n, seed=3, magnitude=0.8)
               for n in ("backlash", "spring_hysteresis", "thermal_drift")]
    r = twin.simulate(baseline, effects, duration_s=120, seed=3, record_temp=True)
    return GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c),
                            baseline)


def test_pieces_give_exactly_the_whole_logs_columns(history_log):
    whole = stream.columns(history_log, TERMS, slice(0, len(history_log)))
    cut = np.empty_like(whole)
    covered = np.zeros(len(history_log), dtype=int)
    for a, b, keep, view in stream.pieces(history_log, size=1700):
        cut[a:b] = stream.columns(view, TERMS, keep)
        covered[a:b] += 1
    assert np.all(covered == 1)
    scale = np.abs(whole).max(axis=(0, 1)) + 1e-300
    assert np.max(np.abs(cut - whole).max(axis=(0, 1)) / scale) < 1e-9


def test_streamed_and_kept_gram_summaries_agree(history_log, monkeypatch):
    terms = list(TERMS[:6])
    kept = selection.build_problem(history_log, terms, keep_columns=True)
    monkeypatch.setattr(stream, "PIECE_SAMPLES", 1300)
    streamed = selection.build_problem(history_log, terms, keep_columns=False)
    assert streamed.x is None and streamed.y is None
    assert np.allclose(streamed.gram, kept.gram, rtol=1e-9, atol=1e-12)
    assert np.allclose(streamed.xty, kept.xty, rtol=1e-9, atol=1e-12)
    assert np.allclose(streamed.yty, kept.yty, rtol=1e-12)


@given(arrays(float, st.tuples(st.integers(1, 400), st.just(3)),
              elements=st.floats(-1e3, 1e3)),
       st.lists(st.integers(1, 97), min_size=1, max_size=8))
def test_tails_give_numpys_percentile(values, cuts):
    tails = stream.Tails(len(values), columns=3)
    at, i = 0, 0
    while at < len(values):
        step = cuts[i % len(cuts)]
        tails.add(values[at:at + step])
        at += step
        i += 1
    assert np.allclose(tails.percentile(), np.percentile(np.abs(values), 99, axis=0),
                       rtol=1e-12, atol=1e-12)


def test_column_cache_round_trips_in_float32(tmp_path):
    rng = np.random.default_rng(0)
    cache = stream.ColumnCache(tmp_path, width=5)
    parts = [rng.normal(size=(n, 6, 5)) for n in (7, 3, 11)]
    at = 0
    for p in parts:
        cache.write(at, p)
        at += len(p)
    whole = np.concatenate(parts)
    assert np.allclose(cache.read(4, 15), whole[4:15].astype(np.float32))
    with pytest.raises(AssertionError):
        cache.write(0, parts[0])              # out of order


def test_a_long_logs_play_states_in_pieces_are_the_whole_scans(history_log, monkeypatch):
    """Play states of a long log are scanned a piece at a time, each piece from the outputs
    of the sample before it: exactly the states of one scan over the whole log (a running
    clamp has no rounding), and the state handed to the next view is the whole scan's."""
    from delta6.diagnosis import data as data_mod
    from delta6.diagnosis.signals import play_output, play_state

    radii = (0.01, 0.05)
    whole = play_state(history_log.theta, radii)
    monkeypatch.setattr(data_mod, "PIECE", 777)
    handoff = 5 * 777 + 13
    log = history_log.piece(0, len(history_log), handoff=handoff)
    assert len(log) > 5 * 777
    assert np.array_equal(log.play_state(radii), whole)
    assert np.array_equal(log.carry_out[("play", radii)],
                          play_output(history_log.theta, radii)[handoff])


@given(arrays(float, (40, 3), elements=st.floats(-3, 3)),
       arrays(float, 40, elements=st.floats(0.5, 1.5)), st.integers(1, 4), st.integers(1, 3))
def test_smooth_velocity_is_the_slope_of_the_local_polynomial_fit(x, dt, half_width, degree):
    """Inside the log, the velocity is the slope at the window's centre of the least-squares
    polynomial through the window (np.polyfit); np.gradient at the ends."""
    from delta6.diagnosis.signals import smooth_velocity

    t = np.cumsum(dt)
    got = smooth_velocity(x, t, half_width, step=0.9, degree=degree)
    k = np.arange(-half_width, half_width + 1, dtype=float) * 0.9
    for c in range(half_width, len(x) - half_width):
        window = x[c - half_width:c + half_width + 1]
        want = np.polyfit(k, window, min(degree, 2 * half_width))[-2]
        np.testing.assert_allclose(got[c], want, rtol=1e-9, atol=1e-9)
    edge = np.gradient(x, t, axis=0)
    assert np.array_equal(got[:half_width], edge[:half_width])
    assert np.array_equal(got[-half_width:], edge[-half_width:])


def test_predictions_kept_on_disk_are_those_kept_in_memory(history_log, tmp_path):
    """The ladder's held-out predictions wait in scratch files on long logs: read back, they
    are the float32 predictions kept in memory, and the p99s do not change."""
    terms = [t for t in TERMS if t.name in ("backlash", "spring_hysteresis")]
    problem = selection.build_problem(history_log, terms, keep_columns=True)
    models = {name: (problem.cols([name]), selection.fold_coefficients(problem, [name]))
              for name in ("backlash", "spring_hysteresis")}
    args = (history_log, terms, problem.bounds, problem.fold_of_block, models, set(models))
    in_memory = stream.predict(*args, x_all=problem.x)
    on_disk = stream.predict(*args, x_all=problem.x, spill=tmp_path)
    for name in models:
        assert np.array_equal(on_disk["p99"][name], in_memory["p99"][name])
        got = on_disk["pred"][name].read()
        assert got.dtype == np.float32 and np.array_equal(got, in_memory["pred"][name].read())
    assert not list(tmp_path.iterdir())                     # each file goes once read


def test_a_second_cache_stores_only_its_new_columns_and_reads_the_rest_from_the_first(
        tmp_path):
    """A second pass that changes one family writes that family's columns only; read back,
    its columns are those it was given (float32), whichever cache holds them."""
    rng = np.random.default_rng(1)
    first = stream.ColumnCache(tmp_path, width=5)
    (tmp_path / "second").mkdir()
    source = np.array([0, -1, 3, -1, -1, 4])              # columns 1, 3 and 4 are new
    second = stream.ColumnCache(tmp_path / "second", width=6, reuse=(first, source))
    x1, x2 = rng.normal(size=(23, 6, 5)), rng.normal(size=(23, 6, 6))
    x2[:, :, source >= 0] = x1[:, :, source[source >= 0]]
    for a, b in ((0, 9), (9, 23)):
        first.write(a, x1[a:b])
        second.write(a, x2[a:b])
    assert second.path.stat().st_size == 23 * 6 * 3 * 4
    want = x2.astype(np.float32)
    assert np.array_equal(second.read(4, 17), want[4:17].astype(float))
    assert np.array_equal(second.rows([20, 2, 7]), want[[20, 2, 7]])
    assert np.array_equal(first.rows([5]), x1[[5]].astype(np.float32))


def test_the_columns_a_second_pass_reuses_are_those_of_its_unchanged_families():
    import dataclasses

    terms = list(TERMS[:3])
    changed = dataclasses.replace(terms[1], param_names=terms[1].param_names[:2])
    widths = [len(t.param_names) for t in terms]
    got = stream.reused_columns(terms, [terms[0], changed, terms[2]])
    assert np.array_equal(got, list(range(widths[0])) + [-1, -1]
                          + list(range(widths[0] + widths[1], sum(widths))))
