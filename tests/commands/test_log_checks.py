"""Logs as other people's rigs and simulators write them: every command that scores or fits a
model on a log refuses a broken one in one line (status 2), whatever the command; a log that
is only written differently (a byte-order mark, quoted names) is read."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.cli import main
from delta6.link.logfile import LogWriter, read_log

from conftest import DESIGNS
from support.logs import synthetic_log

DESIGN = str(DESIGNS / "delta6.toml")
STIFF = str(DESIGNS / "stiff.toml")


def write(path, log, meta=None):
    with LogWriter(path, {"design": "delta6"} if meta is None else meta) as w:
        w.write_block(log.t, log.theta, log.wrench)
    return path


@pytest.fixture(scope="module")
def clean(baseline):
    return synthetic_log(baseline, "none", n=2500)


def one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def broken(log, how):
    out = type(log)(t=log.t.copy(), theta=log.theta.copy(), wrench=log.wrench.copy())
    if how == "wrap":
        out.theta[700:, 1] += 2 * np.pi              # a 14-bit count wrapped on joint 2
    elif how == "milliseconds":
        out.t = out.t * 1000.0
    elif how == "newton-millimetres":
        out.wrench[:, 3:] *= 1000.0
    elif how == "degrees":
        out.theta = np.degrees(out.theta)
    elif how == "glitch":
        out.theta[1234, 0] = 3.0                     # one corrupt row, far outside the box
    return out


@pytest.mark.parametrize("how, words", [
    ("wrap", "theta_e2 jumps by +6.2"),
    ("milliseconds", "t must be in seconds"),
    ("newton-millimetres", "far outside the design's range"),
    ("degrees", "degrees"),
    ("glitch", "1 sample has an encoder angle far outside the joint box, the first at t ="),
])
@pytest.mark.parametrize("command", ["evaluate", "diagnose", "calibrate"])
def test_a_broken_log_is_refused_by_every_command(tmp_path, clean, capsys, how, words,
                                                   command):
    path = write(tmp_path / "bad.csv", broken(clean, how))
    extra = {"diagnose": ["--quiet"], "calibrate": ["--quiet", "-o", str(tmp_path / "c.toml")]
             }.get(command, [])
    assert main([command, str(path), "--design", DESIGN, *extra]) == 2
    assert words in one_line(capsys)


def test_a_corrupt_row_removed_reads_as_a_lost_sample(tmp_path, clean, capsys):
    """What the refusal of a corrupt row advises works: the log without that row is scored."""
    keep = np.ones(len(clean.t), bool)
    keep[1234] = False
    cut = type(clean)(t=clean.t[keep], theta=clean.theta[keep], wrench=clean.wrench[keep])
    assert main(["evaluate", str(write(tmp_path / "cut.csv", cut)), "--design", DESIGN]) == 0
    assert "analytical" in capsys.readouterr().out


def test_evaluate_scores_a_clean_short_log(tmp_path, clean, capsys):
    short = type(clean)(t=clean.t[:300], theta=clean.theta[:300], wrench=clean.wrench[:300])
    assert main(["evaluate", str(write(tmp_path / "short.csv", short)), "--design",
                 DESIGN]) == 0
    assert "analytical" in capsys.readouterr().out


def test_a_design_named_without_its_hash_is_held_to_the_name(tmp_path, clean, capsys):
    path = write(tmp_path / "stiff.csv", clean, meta={"design": "stiff"})
    assert main(["evaluate", str(path), "--design", DESIGN]) == 2
    assert "names design 'stiff'" in one_line(capsys)
    assert main(["diagnose", str(path), "--design", DESIGN, "--quiet"]) == 2
    assert "names design 'stiff'" in one_line(capsys)
    # Without --design the diagnosis takes the shipped design of that name.
    from delta6.commands.diagnose import choose_design
    assert choose_design(read_log(path), path, None, False).name == "stiff.toml"
    unknown = write(tmp_path / "mine.csv", clean, meta={"design": "my-variant"})
    assert main(["diagnose", str(unknown), "--quiet"]) == 2
    assert "not a shipped design" in one_line(capsys)
    # A log that names no design is taken as it is.
    from delta6.core.calibration import CalibrationError, check_log_meta
    from delta6.core.design import load
    check_log_meta({}, load(STIFF))
    check_log_meta({"design": "stiff"}, load(STIFF))
    with pytest.raises(CalibrationError, match="names design 'delta6'"):
        check_log_meta({"design": "delta6"}, load(STIFF))


def test_the_first_missing_value_in_the_file_is_named(tmp_path, clean, capsys):
    path = write(tmp_path / "holes.csv", clean)
    lines = path.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    cells = lines[header + 100].split(",")
    cells[8] = "nan"                                 # Fy, row 100
    lines[header + 100] = ",".join(cells)
    cells = lines[header + 2000].split(",")
    cells[3] = ""                                    # theta_e3, row 2000: later in the file
    lines[header + 2000] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    assert main(["evaluate", str(path), "--design", DESIGN]) == 2
    err = one_line(capsys)
    assert f"missing or NaN Fy value at line {header + 101}" in err
    assert "2 incomplete rows" in err and "--complete-rows" in err
    # What the line points to: the complete rows, every other one kept, the gaps left gaps.
    kept = tmp_path / "kept.csv"
    assert main(["convert", str(path), str(kept), "--complete-rows"]) == 0
    assert "2498 samples" in capsys.readouterr().err
    log, full = read_log(kept), read_log(path, require_complete_rows=False)
    gone = np.array([99, 1999])
    assert len(log) == len(full) - 2 and not np.isin(full.t[gone], log.t).any()
    for column in ("t", "theta", "wrench"):
        assert np.array_equal(getattr(log, column), np.delete(getattr(full, column), gone, 0))
    assert main(["evaluate", str(kept), "--design", DESIGN]) == 0


def test_spreadsheet_habits_are_read(tmp_path, clean):
    path = write(tmp_path / "plain.csv", clean)
    text = path.read_text()
    lines = text.splitlines()
    header = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    lines[header] = ",".join(f'"{c}"' for c in lines[header].split(","))
    quoted = tmp_path / "quoted.csv"
    quoted.write_text("\n".join(lines) + "\n")
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + text.encode("ascii"))
    want = read_log(path)
    for other in (quoted, bom):
        got = read_log(other)
        np.testing.assert_array_equal(got.theta, want.theta)
        np.testing.assert_array_equal(got.wrench, want.wrench)
        assert got.meta.get("design") == "delta6"


@settings(max_examples=25, deadline=None)
@given(st.floats(1e3, 1e6), st.integers(0, 5))
def test_table_columns_never_run_into_each_other(big, axis):
    from delta6.evaluation.tablev import format_table
    values = [1.0] * 6
    values[axis] = big
    rows = [{"estimator": "analytical", "p95_pct": values, "p99_pct": values,
             "max_pct": values}]
    text = format_table({"rows": rows, "samples": 10})
    for line in text.splitlines()[2:]:
        numbers = line.split()[2:]
        assert len(numbers) == 6 and float(numbers[axis]) == pytest.approx(big, abs=0.01)


def test_a_long_log_without_scratch_room_is_refused_before_the_work(tmp_path, baseline,
                                                                     capsys, monkeypatch):
    """A log past the in-memory columns' length keeps them in the scratch folder (13 GB at
    2 x 10^6 samples): without that room the diagnosis says so in one line, at once."""
    from collections import namedtuple

    from delta6.diagnosis import run
    log = synthetic_log(baseline, "none", n=run.KEEP_COLUMNS_SAMPLES + 1000)
    path = write(tmp_path / "long.csv", log)
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(run.shutil, "disk_usage", lambda _: usage(10**9, 10**9 - 10**6, 10**6))
    assert main(["diagnose", str(path), "--design", DESIGN, "--quiet"]) == 2
    err = one_line(capsys)
    assert "GB of scratch disk" in err and "TMPDIR" in err
    import re
    need = float(re.search(r"about ([0-9.]+) GB", err).group(1))
    per_column = run.SCRATCH_MARGIN * len(log.t) * 6 * 4 / 1e9     # float32, six axes
    assert 200 * per_column <= need <= 400 * per_column             # ~270 columns


def test_milliseconds_are_caught_by_the_headers_rate(tmp_path, clean, capsys):
    """A 1 kHz log in milliseconds has rows 1.0 apart, within the step's limit; its header's
    rate_hz (what `delta6 log` writes) gives it away. A log whose rows match its rate reads."""
    fast = type(clean)(t=np.arange(len(clean.t)) * 1.0, theta=clean.theta,
                       wrench=clean.wrench)
    path = write(tmp_path / "ms.csv", fast, meta={"design": "delta6", "rate_hz": "1000"})
    assert main(["evaluate", str(path), "--design", DESIGN]) == 2
    assert "rate_hz=1000" in one_line(capsys)
    right = write(tmp_path / "s.csv", clean, meta={"design": "delta6", "rate_hz": "50"})
    assert main(["evaluate", str(right), "--design", DESIGN]) == 0
    capsys.readouterr()


def test_a_byte_order_mark_does_not_let_other_text_in(tmp_path, clean, capsys):
    path = write(tmp_path / "plain.csv", clean)
    text = path.read_text().replace("\n0.040000,", "\n0.0400\u0661\u0662,", 1)
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert main(["evaluate", str(bom), "--design", DESIGN]) == 2
    assert "non-ASCII" in one_line(capsys)
