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
    assert partial.read_text().strip().splitlines()[-1].startswith("0.000000,0,0,0")
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


def test_exception_inside_context_keeps_the_data_in_the_partial_file(tmp_path):
    path = tmp_path / "run.csv"
    with pytest.raises(RuntimeError):
        with LogWriter(path) as log:
            log.write(0.0, [0] * 6, [0] * 6)
            raise RuntimeError("interrupted")
    # The rows are kept, but a file without .partial is complete, and this one is not.
    assert not path.exists() and len(read_log(path.with_name("run.csv.partial"))) == 1


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
    (lambda s: s.replace("0.02,0.1", "0.02,nan", 1), "NaN theta_e1 value at line 4"),
    (lambda s: s.replace("0.04,", "0.01,"), "not strictly increasing at line 5"),
    (lambda s: s.replace("0.02,0.1", "0.02,abc", 1), "'abc' is not a number"),
    (lambda s: s.replace("0.02,0.1", "0.02,0.#1", 1),
     "line 4, column theta_e1: '0.#1' is not a number"),
    (lambda s: s.replace("\n0.02,", "\n#0.02,", 1), "line 4, column t: '#0.02' is not a number"),
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


def test_times_are_written_exactly_at_any_length_of_run(tmp_path):
    """Device times are whole microseconds: after 28 h at 1800 Hz neighbouring rows still
    differ, and every microsecond survives (9 significant digits lost them past 1000 s)."""
    t_us = np.array([100_000_000_000 + k * 555 for k in range(5)] + [123_456_789_012])
    path = tmp_path / "long.csv"
    with LogWriter(path, optional=("host_t",)) as log:
        log.write_block(t_us / 1e6, np.zeros((6, 6)), np.zeros((6, 6)),
                        host_t=np.full(6, 98765.4321))
    back = read_log(path)
    assert np.array_equal(np.round(back.t * 1e6).astype(np.int64), t_us)
    assert np.all(np.diff(back.t[:5]) > 0) and back.host_t[0] == 98765.4321
    assert path.read_text().splitlines()[-1].startswith("123456.789012,")


def test_infinite_values_are_refused_with_their_line(tmp_path):
    path = tmp_path / "inf.csv"
    path.write_text(good_text(5).replace("0.06,0.1,0.1,0.1", "0.06,0.1,inf,0.1"))
    with pytest.raises(LogError, match="line 6: infinite value in column theta_e2"):
        read_log(path)
    path.write_text(good_text(5).replace("0.04,", "-inf,"))
    with pytest.raises(LogError, match="line 5: infinite value in column t"):
        read_log(path, require_complete_rows=False)


def test_a_cut_last_row_of_a_partial_file_is_not_read(tmp_path):
    """A writer killed in the middle of a row leaves a cut number, which is a made-up number:
    the reader of a .partial file drops an unterminated last row."""
    text = good_text(4)
    partial = tmp_path / "run.csv.partial"
    partial.write_text(text[:-5])                      # "0.06,0.1,...,0." : cut
    data = read_log(partial)
    assert len(data) == 3 and data.meta["cut_row_dropped"] == "1"
    complete = tmp_path / "run.csv"                    # a complete file keeps its last row
    complete.write_text(text[:-1])
    assert len(read_log(complete)) == 4


def test_a_full_disk_leaves_only_whole_rows(tmp_path, monkeypatch):
    """A write that fails half way (ENOSPC) is undone to the last whole row, the error names
    the file and the rows kept, and what is on disk reads back as exactly those rows."""
    import errno
    import os

    real_write = os.write
    budget = {"bytes": 2000}

    def disk_with_room(fd, data):
        if budget["bytes"] <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        n = min(len(data), budget["bytes"])
        budget["bytes"] -= n
        return real_write(fd, bytes(data[:n]))        # a short write, then ENOSPC

    path = tmp_path / "full.csv"
    log = LogWriter(path, optional=("seq",))
    monkeypatch.setattr("delta6.link.logfile.os.write", disk_with_room)
    with pytest.raises(LogError) as info:
        for k in range(100):
            t = np.arange(10) * 0.001 + k * 0.01
            log.write_block(t, np.full((10, 6), 0.123456789), np.full((10, 6), -1.5),
                            seq=np.arange(10) + 10 * k)
    message = str(info.value)
    assert "No space left on device" in message and str(log.partial) in message
    kept = log.rows
    assert f"keeps the {kept} rows written before" in message and kept % 10 == 0
    monkeypatch.undo()
    back = read_log(log.close(complete=False))
    assert len(back) == kept and np.array_equal(back.seq, np.arange(kept))
    assert np.all(back.theta.astype(np.float32) == np.float32(0.123456789))


def test_refusing_to_overwrite(tmp_path):
    path = tmp_path / "keep.csv"
    path.write_text("precious")
    with pytest.raises(LogError, match="keep.csv exists"):
        LogWriter(path, overwrite=False)
    path.unlink()
    (tmp_path / "keep.csv.partial").write_text("left by a crash")
    with pytest.raises(LogError, match="keep.csv.partial exists"):
        LogWriter(path, overwrite=False)
    assert (tmp_path / "keep.csv.partial").read_text() == "left by a crash"


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
    with pytest.raises(logfile.LogError, match=f"line {bad + 1}, column theta_e1:"):
        logfile.read_log(path)


def test_a_spreadsheets_padded_header_lines_read_as_written(tmp_path):
    """Saved from a spreadsheet, every '#' line gains the table's commas: the schema read
    '1,,,,' and was refused as unsupported."""
    path = tmp_path / "a.csv"
    with LogWriter(path, {"design": "delta6", "rate_hz": "50"}) as w:
        w.write_block(np.arange(3) * 0.02, np.zeros((3, 6)), np.ones((3, 6)))
    padded = tmp_path / "padded.csv"
    padded.write_text("".join(line + (",,,,,,,,,,,," if line.startswith("#") else "") + "\n"
                              for line in path.read_text().splitlines()))
    a, b = read_log(path), read_log(padded)
    assert a.meta == b.meta and np.array_equal(a.theta, b.theta)


@pytest.mark.parametrize("t, words", [([0.0, 0.02, 0.02, 0.04], "a duplicated row"),
                                      ([0.0, 0.04, 0.02, 0.06], "rows out of order")])
def test_time_that_does_not_increase_says_how(tmp_path, t, words):
    path = tmp_path / "t.csv"
    with LogWriter(path, {"design": "delta6"}) as w:
        for k, tk in enumerate(t):
            w.write(tk, np.zeros(6), np.full(6, float(k)))
    with pytest.raises(LogError, match=words):
        read_log(path)


def test_columns_the_format_does_not_know_are_left_out_and_named(tmp_path):
    """A spreadsheet's note column (text) was refused as 'not a number'; an index column was
    dropped unnamed."""
    path = tmp_path / "a.csv"
    with LogWriter(path, {"design": "delta6"}) as w:
        w.write_block(np.arange(3) * 0.02, np.zeros((3, 6)), np.ones((3, 6)))
    lines = path.read_text().splitlines()
    edited = [ln if ln.startswith("#") else ("idx," + ln + ",note" if ln.startswith("t,")
                                            else f"{k}," + ln + ",ok")
              for k, ln in enumerate(lines)]
    (tmp_path / "b.csv").write_text("\n".join(edited) + "\n")
    a, b = read_log(path), read_log(tmp_path / "b.csv")
    assert np.array_equal(a.theta, b.theta) and np.array_equal(a.wrench, b.wrench)
    assert b.ignored_columns == ("idx", "note") and a.ignored_columns == ()
