"""Every file the command line reads, damaged at random, through the command that reads it:
the answer is the work done (status 0) or one line naming the problem (status 2), never a
traceback. Designs (``delta6 design``), logs in CSV and MCAP (``delta6 convert``, which reads
them whole), captures (``delta6 decode``), calibrations (``delta6 evaluate --calibration``)."""
from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.cli import main
from delta6.core import calibration as C
from delta6.core.design import load
from delta6.link import protocol as P
from delta6.link.logfile import LogWriter
from delta6.sim.simdevice import SimulatedDevice

from conftest import DESIGNS

#: An edit of a file: (position, kind, byte); kinds flip a bit, delete a stretch, insert a
#: byte, or cut the file there.
edits = st.lists(st.tuples(st.integers(0, 2**31), st.integers(0, 3), st.integers(0, 255)),
                 min_size=1, max_size=6)


def damaged(data: bytes, changes) -> bytes:
    out = bytearray(data)
    for position, kind, value in changes:
        if not out:
            break
        at = position % len(out)
        if kind == 0:
            out[at] ^= 1 << (value % 8)
        elif kind == 1:
            del out[at:at + 1 + value % 40]
        elif kind == 2:
            out.insert(at, value)
        else:
            del out[at:]
    return bytes(out)


def run_cli(argv) -> None:
    err_stream, out_stream = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err_stream), contextlib.redirect_stdout(out_stream):
        status = main(argv)
    err = err_stream.getvalue()
    assert "Traceback" not in err
    assert status in (0, 2), (status, err)
    if status == 2:
        assert err.count("\n") == 1 and ": error: " in err, err


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    """A valid file of each kind to damage."""
    folder = tmp_path_factory.mktemp("seeds")
    rng = np.random.default_rng(0)
    log = folder / "log.csv"
    with LogWriter(log, {"design": "delta6", "design_hash": "0x535534af"},
                   optional=("seq", "status")) as w:
        n = 30
        w.write_block(np.arange(n) * 0.004, rng.normal(0, 0.05, (n, 6)),
                      rng.normal(0, 2, (n, 6)), seq=np.arange(n), status=np.zeros(n))
    mcap = folder / "log.mcap"
    assert main(["convert", str(log), str(mcap)]) == 0
    sim = SimulatedDevice()
    sim.write(P.encode_command(P.Command.SET_MODE, 1, 2))
    sim.write(P.encode_command(P.Command.START, 2, 500))
    sim.advance(0.1)
    capture = sim.read()
    sim.close()
    calibration = C.dumps(C.neutral(load(DESIGNS / "delta6.toml"), "fuzz")).encode()
    return {"design": (DESIGNS / "delta6.toml").read_bytes(), "csv": log.read_bytes(),
            "mcap": mcap.read_bytes(), "capture": capture, "calibration": calibration,
            "log_path": log}


@settings(max_examples=25)        # a valid design runs its report (0.3 s): fewer examples
@given(changes=edits)
def test_damaged_design_files(seeds, tmp_path_factory, changes):
    path = tmp_path_factory.mktemp("d") / "d.toml"
    path.write_bytes(damaged(seeds["design"], changes))
    run_cli(["design", str(path), "--json"])


@settings(max_examples=80)
@given(changes=edits, kind=st.sampled_from(["csv", "mcap"]))
def test_damaged_logs(seeds, tmp_path_factory, changes, kind):
    folder = tmp_path_factory.mktemp("l")
    path = folder / f"in.{kind}"
    path.write_bytes(damaged(seeds[kind], changes))
    run_cli(["convert", str(path), str(folder / "out.csv")])


@settings(max_examples=80)
@given(changes=edits)
def test_damaged_captures(seeds, tmp_path_factory, changes):
    folder = tmp_path_factory.mktemp("c")
    path = folder / "c.bin"
    path.write_bytes(damaged(seeds["capture"], changes))
    run_cli(["decode", str(path), "-o", str(folder / "out.csv")])


@settings(max_examples=60)
@given(changes=edits)
def test_damaged_calibrations(seeds, tmp_path_factory, changes):
    folder = tmp_path_factory.mktemp("k")
    path = folder / "cal.toml"
    path.write_bytes(damaged(seeds["calibration"], changes))
    run_cli(["evaluate", str(seeds["log_path"]), "--calibration", str(path)])


@settings(max_examples=60)
@given(blob=st.binary(max_size=4000), reader=st.sampled_from(["design", "convert", "decode"]))
def test_random_bytes_in_place_of_any_file(tmp_path_factory, blob, reader):
    folder = tmp_path_factory.mktemp("r")
    path = folder / "in"
    path.write_bytes(blob)
    argv = {"design": ["design", str(path)],
            "convert": ["convert", str(path), str(folder / "out.csv")],
            "decode": ["decode", str(path), "-o", str(folder / "out.csv")]}[reader]
    run_cli(argv)
