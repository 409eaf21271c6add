"""The shared CSV log format: round trip, crash safety, and clear errors on bad files."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.link.logfile import CORE_COLUMNS, PARTIAL_SUFFIX, LogError, LogWriter, read_log

finite32 = st.floats(-1e6, 1e6, allow_nan=False, width=32)


@given(st.integers(1, 40).flatmap(lambda n: st.tuples(
    arrays(float, (n, 6), elements=finite32), arrays(float, (n, 6), elements=finite32),
    arrays(float, n, elements=st.floats(-40, 120, width=32)))), st.booleans())
def test_round_trip_is_exact_for_float32_values(tmp_path_factory, data, blockwise):
    theta, wrench, temp = data
    n = len(theta)
    t = np.arange(n) * 0.004 + 12.5
    path = tmp_path_factory.mktemp("log") / "x.csv"
    with LogWriter(path, {"design": "delta6"}, optional=("seq", "status", "temp_c")) as log:
        if blockwise:
            log.write_block(t, theta, wrench, seq=np.arange(n), status=np.zeros(n),
                            temp_c=temp)
        else:
            for i in range(n):
                log.write(t[i], theta[i], wrench[i], seq=i, status=0, temp_c=temp[i])
    back = read_log(path)
    assert np.array_equal(back.theta.astype(np.float32), theta.astype(np.float32))
    assert np.array_equal(back.wrench.astype(np.float32), wrench.astype(np.float32))
    assert np.array_equal(back.seq, np.arange(n)) and back.seq.dtype == np.int64
    assert np.allclose(back.t, t, rtol=1e-9)
    assert back.meta["design"] == "delta6" and back.meta["schema"] == "1"


def test_partial_file_until_clean_close(tmp_path):
    path = tmp_path / "run.csv"
    log = LogWriter(path, flush_every=1)
    log.write(0.0, [0] * 6, [1] * 6)
    partial = tmp_path / ("run.csv" + PARTIAL_SUFFIX)
    assert partial.exists() and not path.exists()
    # What a crash leaves behind is readable up to the last row.
    assert partial.read_text().strip().splitlines()[-1].startswith("0,0,0")
    log.close()
    assert path.exists() and not partial.exists()
    assert len(read_log(path)) == 1


def test_blocks_reach_the_os_at_once_and_the_disk_every_flush_every_rows(tmp_path,
                                                                           monkeypatch):
    synced = []
    monkeypatch.setattr("delta6.link.logfile.os.fsync", lambda fd: synced.append(fd))
    path = tmp_path / "run.csv"
    partial = tmp_path / ("run.csv" + PARTIAL_SUFFIX)
    log = LogWriter(path, flush_every=25)
    for i in range(10):
        t = np.arange(10) * 0.001 + i * 0.01
        log.write_block(t, np.zeros((10, 6)), np.ones((10, 6)))
        # A crash now would leave every row written so far in the .partial file.
        assert len(partial.read_text().strip().splitlines()) - 3 == 10 * (i + 1)
    assert len(synced) == 3          # after 30, 60 and 90 rows, not after every block
    log.close()
    assert len(synced) == 4 and len(read_log(path)) == 100


def test_exception_inside_context_still_keeps_the_data(tmp_path):
    path = tmp_path / "run.csv"
    with pytest.raises(RuntimeError):
        with LogWriter(path) as log:
            log.write(0.0, [0] * 6, [0] * 6)
            raise RuntimeError("port vanished")
    assert len(read_log(path)) == 1


def test_missing_values_allowed_when_asked(tmp_path):
    path = tmp_path / "wrench_only.csv"
    with LogWriter(path) as log:
        log.write(0.0, None, [1, 2, 3, 4, 5, 6])
        log.write(0.1, None, [1, 2, 3, 4, 5, 6])
    with pytest.raises(LogError, match="theta_e"):
        read_log(path)
    data = read_log(path, require_complete_rows=False)
    assert np.isnan(data.theta).all() and data.wrench[1, 5] == 6


def good_text(rows=3):
    head = ",".join(CORE_COLUMNS)
    body = [",".join([str(i * 0.02)] + ["0.1"] * 12) for i in range(rows)]
    return "\n".join(["# delta6-log schema=1", head] + body) + "\n"


@pytest.mark.parametrize("mutate, words", [
    (lambda s: s.replace(",Fz", ""), "missing column(s) Fz"),
    (lambda s: s.replace("0.02,0.1,", "0.02,", 1), "line 4 has 12 fields, expected 13"),
    (lambda s: s.replace("t,theta_e1", "time,theta_e1"), "missing column(s) t"),
    (lambda s: s.replace(",Mz\n", "\n").replace(",0.1\n", "\n"), "missing column(s) Mz"),
    (lambda s: s.replace("0.02,0.1", "0.02,nan", 1), "NaN theta_e value on line 4"),
    (lambda s: s.replace("0.04,", "0.01,"), "not strictly increasing at line 5"),
    (lambda s: s.replace("0.02,0.1", "0.02,abc", 1), "'abc' is not a number"),
    (lambda s: s.replace("schema=1", "schema=9"), "schema 9"),
    (lambda s: "\n".join(s.splitlines()[:2]), "no samples"),
])
def test_bad_logs_are_named(tmp_path, mutate, words):
    path = tmp_path / "bad.csv"
    path.write_text(mutate(good_text()))
    with pytest.raises(LogError) as info:
        read_log(path)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_good_text_reads(tmp_path):
    path = tmp_path / "good.csv"
    path.write_text(good_text())
    assert len(read_log(path)) == 3


@given(st.binary(max_size=300))
def test_fuzzed_bytes_give_log_error_or_data(tmp_path_factory, blob):
    path = tmp_path_factory.mktemp("fz") / "f.csv"
    path.write_bytes(blob)
    try:
        read_log(path)
    except LogError as exc:
        assert "\n" not in str(exc)


@given(st.lists(st.text(alphabet="0123456789.,-enai \n#", max_size=60), max_size=8))
def test_fuzzed_rows_after_a_valid_header(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("fz") / "f.csv"
    path.write_text(",".join(CORE_COLUMNS) + "\n" + "\n".join(rows))
    try:
        data = read_log(path)
    except LogError:
        return
    assert np.isfinite(data.t).all() and (np.diff(data.t) > 0).all()
    assert not np.isnan(data.theta).any()


def test_reading_in_chunks_gives_the_same_log_and_line_numbers(tmp_path, monkeypatch):
    from delta6.link import logfile
    rng = np.random.default_rng(5)
    n = 257
    path = tmp_path / "chunks.csv"
    with logfile.LogWriter(path, {"design": "delta6"}, optional=("temp_c",)) as w:
        w.write_block(np.arange(n) * 0.02, rng.normal(size=(n, 6)), rng.normal(size=(n, 6)),
                      temp_c=rng.normal(size=n))
    whole = logfile.read_log(path)
    monkeypatch.setattr(logfile, "READ_CHUNK_ROWS", 10)
    cut = logfile.read_log(path)
    for name in ("t", "theta", "wrench", "temp_c"):
        assert np.array_equal(getattr(whole, name), getattr(cut, name))
    lines = path.read_text().splitlines()
    bad = next(i for i, ln in enumerate(lines) if ln and ln[0].isdigit()) + 131
    lines[bad] = lines[bad].replace(",", ",x", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(logfile.LogError, match=f"line {bad + 1}:"):
        logfile.read_log(path)
