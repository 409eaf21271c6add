"""Faults injected at random points while ``delta6 log`` runs, as separate processes: the
host killed by SIGINT, SIGTERM, SIGHUP or SIGKILL, the device side killed, random bytes both
ways, a full disk. After each, the invariants of docs/reliability.md must hold:

- every record received is in the log (or its .partial file after SIGKILL);
- no row is made up: each one is a record the device sent, exactly;
- every exit is a documented status, with one line saying how it ended, never a traceback;
- no process is left behind.

The device side is a simulated Delta6 on a pseudo-terminal in a process of its own
(tests/support/ptydevice.py), which keeps a clean copy of all it sent. Every wait is bounded.
"""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from delta6.cli import main
from delta6.link import cobs
from delta6.link import protocol as P
from delta6.link.bulkdecode import decode_capture
from delta6.link.logfile import LogError, read_log

from conftest import ROOT

SUPPORT = Path(__file__).resolve().parents[1] / "support"
# This checkout's host package first: the venv's editable install may point at another.
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "host"), str(ROOT / "tests")])}
#: How each kind of end may look: exit status and the last line of stderr.
STOPPED = 0


def start_device(tmp_path: Path, *options: str) -> tuple[subprocess.Popen, str, Path]:
    sent = tmp_path / "sent.bin"
    proc = subprocess.Popen([sys.executable, str(SUPPORT / "ptydevice.py"),
                             "delta6sim://?rate=500", "--sent", str(sent),
                             "--received", str(received_file(sent)), *options],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    port = proc.stdout.readline().strip()
    assert port.startswith("/dev/"), proc.stderr.read()
    return proc, port, sent


def received_file(sent: Path) -> Path:
    """Where the device process keeps the bytes it received (next to those it sent)."""
    return sent.with_name("received.bin")


def delta6(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "delta6", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV)


def start_log(port: str, tmp_path: Path, name: str, *options: str,
              raw: bool = True) -> tuple[subprocess.Popen, Path, Path]:
    out, capture = tmp_path / f"{name}.csv", tmp_path / f"{name}.bin"
    proc = delta6("log", "--port", port, "-o", str(out), "--capture", str(capture), "--rate",
                  "500", *(["--raw"] if raw else []), *options)
    return proc, out, capture


def wait_for_rows(proc: subprocess.Popen, out: Path, rows: int, timeout: float = 30.0) -> None:
    """Until the log's .partial file holds ``rows`` rows (or the log ended)."""
    partial = out.with_name(out.name + ".partial")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if partial.exists() and partial.read_bytes().count(b"\n") > rows + 12:
            return
        time.sleep(0.05)
    raise AssertionError(f"the log did not get going: {proc.poll()}")


def finish(proc: subprocess.Popen, timeout: float = 30.0) -> tuple[int, str]:
    _, err = proc.communicate(timeout=timeout)
    return proc.returncode, err


def stop_device(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
    proc.communicate(timeout=10)


def leftovers(token: str) -> list[str]:
    """Live processes whose command line names ``token`` (our temporary folder)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if token in cmdline and state != "Z":
            found.append(cmdline)
    return found


def device_records(path: Path) -> dict:
    """(seq, time) -> (status, wrench counts, raw counts) of every data record in a byte
    stream (what the device sent, or a capture of what the host received)."""
    cap = decode_capture(path.read_bytes())
    return {(int(s) % 65536, int(t) % 2**32): (int(st), tuple(w), tuple(c))
            for s, t, st, w, c in zip(cap.seq, cap.time_us, cap.status, cap.wrench_counts,
                                      cap.counts)}


def check_rows(log, sent: dict, received: dict, complete: bool) -> None:
    """No row made up: each is a record the device sent, with its status, wrench and angles
    exactly. Nothing lost: the log holds every record received from its first row to its last
    (``complete``: and nothing after the last but what came after it closed)."""
    lsb = np.array([float(v) for v in log.meta["lsb"].split()])
    zero = np.array([int(v) for v in log.meta["zero_counts"].split()])
    keys = [(int(s) % 65536, round(t * 1e6) % 2**32) for s, t in zip(log.seq, log.t)]
    for i, key in enumerate(keys):
        assert key in sent, f"row {i} (seq, time) {key} is no record the device sent"
        status, counts, raw = sent[key]
        assert int(log.status[i]) == status
        expected = np.where(np.array(counts) == -32768, np.nan, np.array(counts) * lsb)
        np.testing.assert_allclose(log.wrench[i], expected, rtol=1e-9, atol=0)
        theta = ((np.array(raw) - zero + 8192) % 16384 - 8192) * (2 * np.pi / 16384)
        bad = ((status >> np.arange(6)) & 1) | (np.array(raw) < 0)      # failed, or not sent
        np.testing.assert_allclose(np.where(bad, np.nan, log.theta[i]),
                                   np.where(bad, np.nan, theta), rtol=1e-7, atol=1e-12)
    order = list(received)                    # in the order the records arrived
    first, last = order.index(keys[0]), order.index(keys[-1])
    assert keys == order[first:last + 1], "a record received is missing from the log"
    if complete:
        # The log stops the stream before it closes: no record arrives after its last row.
        assert last == len(order) - 1, f"{len(order) - last - 1} records received after the log"


def read_partial_or_final(out: Path):
    partial = out.with_name(out.name + ".partial")
    return read_log(out if out.exists() else partial, require_complete_rows=False)


@pytest.fixture(scope="module")
def device(tmp_path_factory):
    """One device process for the tests that kill the host: it outlives every log, as a
    board outlives the programs that read it."""
    folder = tmp_path_factory.mktemp("device")
    proc, port, sent = start_device(folder)
    yield port, sent
    stop_device(proc)
    assert leftovers(str(folder)) == []


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_ends_the_log_with_every_record(device, tmp_path, signum):
    port, sent = device
    rnd = random.Random(int(signum))
    log_proc, out, capture = start_log(port, tmp_path, "stopped")
    wait_for_rows(log_proc, out, rnd.randrange(5, 200))
    log_proc.send_signal(signum)
    status, err = finish(log_proc)
    lines = err.strip().splitlines()
    assert status == STOPPED and "Traceback" not in err, err
    assert lines[-1].endswith(f"(stopped by {signal.Signals(signum).name})"), lines[-1]
    assert lines[-1].startswith(f"{out}: ") and not out.with_name("stopped.csv.partial").exists()
    assert leftovers(str(tmp_path)) == []
    log = read_log(out)                 # complete rows: the raw mode gave angles to all
    check_rows(log, device_records(sent), device_records(capture), complete=True)
    assert f"{len(log)} samples over" in lines[-1]


@pytest.mark.parametrize("gap_s", [0.0, 0.002, 0.02, 0.1])
def test_two_quick_stop_signals_still_close_the_log_whole(device, tmp_path, gap_s):
    """A second Ctrl-C ends the shutdown at once; wherever it lands, the log is closed whole
    under its name, with its summary (it was left as .partial, without the summary). One that
    lands after the summary, as the interpreter exits, may end it by SIGINT."""
    port, sent = device
    log_proc, out, capture = start_log(port, tmp_path, "twice")
    wait_for_rows(log_proc, out, 50)
    log_proc.send_signal(signal.SIGINT)
    time.sleep(gap_s)
    if log_proc.poll() is None:
        log_proc.send_signal(signal.SIGINT)
    status, err = finish(log_proc)
    lines = err.strip().splitlines()
    assert status in (STOPPED, -signal.SIGINT) and "Traceback" not in err, err
    assert lines[-1].startswith(f"{out}: ") and lines[-1].endswith("(stopped by SIGINT)")
    assert not out.with_name("twice.csv.partial").exists() and leftovers(str(tmp_path)) == []
    check_rows(read_log(out), device_records(sent), device_records(capture), complete=False)


def test_sigkill_of_the_log_keeps_what_reached_the_file(device, tmp_path):
    port, sent = device
    log_proc, out, capture = start_log(port, tmp_path, "killed", raw=False)
    wait_for_rows(log_proc, out, random.Random(9).randrange(50, 300))
    log_proc.send_signal(signal.SIGKILL)
    status, _ = finish(log_proc)
    assert status == -signal.SIGKILL and not out.exists() and leftovers(str(tmp_path)) == []
    log = read_partial_or_final(out)           # a cut last row is not read
    assert len(log) > 0
    check_rows(log, device_records(sent), device_records(capture), complete=False)
    # The device, left streaming wrench-only records by the killed log, serves the next log
    # (with angles) cleanly: no record of the old stream comes first, every row has angles.
    again, out2, capture2 = start_log(port, tmp_path, "after", "--duration", "0.4")
    status, err = finish(again)
    assert status == 0, err
    log2 = read_log(out2)                      # complete rows required: angles in every one
    assert log2.status[0] & 0x8000             # the first record of the new stream (marked)
    check_rows(log2, device_records(sent), device_records(capture2), complete=True)


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM])
def test_losing_the_device_process_ends_the_log_with_one_line(tmp_path, signum):
    dev_proc, port, sent = start_device(tmp_path)
    try:
        log_proc, out, capture = start_log(port, tmp_path, "lost")
        wait_for_rows(log_proc, out, random.Random(int(signum)).randrange(20, 200))
        dev_proc.send_signal(signum)
        status, err = finish(log_proc)
    finally:
        stop_device(dev_proc)
    lines = err.strip().splitlines()
    assert status == 2 and "Traceback" not in err, err
    assert lines[-1].startswith(f"delta6 log: error: lost the device on {port}: ")
    log = read_log(out)
    assert lines[-1].endswith(f"{out} keeps the {len(log)} samples received before")
    check_rows(log, device_records(sent), device_records(capture), complete=True)
    assert leftovers(str(tmp_path)) == []


def test_random_bytes_both_ways(tmp_path):
    """Garbage and flipped bits on the line, in both directions: commands are retried, damaged
    records are counted and dropped, and no row is made up or lost on the way to the file."""
    dev_proc, port, sent = start_device(tmp_path, "--noise", "0.05", "--seed", "4")
    try:
        log_proc, out, capture = start_log(port, tmp_path, "noisy", "--duration", "1.5")
        status, err = finish(log_proc)
    finally:
        stop_device(dev_proc)
    # Each command is tried three times: all three garbled at this noise is a 1e-4 chance.
    assert status == 0 and "Traceback" not in err, err
    log = read_log(out)
    h = device_records(capture)
    assert len(log) > 200 and len(h) < len(device_records(sent))     # the noise cost records
    assert f" gaps; {int(np.count_nonzero(log.status & 0xFFF))} flagged; " in err
    check_rows(log, device_records(sent), device_records(capture), complete=True)
    assert leftovers(str(tmp_path)) == []


def test_a_full_disk_ends_the_log_with_whole_rows(tmp_path, capsys, monkeypatch):
    """The disk fills up mid-log (an injected ENOSPC after some kilobytes): one line, status
    2, and the .partial file holds whole rows, each a record received."""
    import errno
    real_write = os.write
    room = {"bytes": 60_000}
    partial = tmp_path / "full.csv.partial"

    def filling(fd, data):
        try:
            on_log = os.readlink(f"/proc/self/fd/{fd}") == str(partial)
        except OSError:
            on_log = False
        if on_log:
            if room["bytes"] <= 0:
                raise OSError(errno.ENOSPC, "No space left on device")
            data = bytes(data[:room["bytes"]])
            room["bytes"] -= len(data)
        return real_write(fd, data)

    monkeypatch.setattr("delta6.link.logfile.os.write", filling)
    capture = tmp_path / "full.bin"
    status = main(["log", "--port", "delta6sim://?rate=1000", "-o", str(tmp_path / "full.csv"),
                   "--raw", "--capture", str(capture), "--duration", "5"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert err[-1].startswith(f"delta6 log: error: cannot write {partial}: No space left on "
                              "device; it keeps the ")
    log = read_log(partial)
    assert f"it keeps the {len(log)} rows written before" in err[-1] and len(log) > 100
    received = device_records(capture)
    check_rows(log, received, received, complete=False)
    assert not (tmp_path / "full.csv").exists()


def test_a_full_disk_while_decoding_is_one_line(tmp_path, capsys, monkeypatch):
    import errno
    capture = tmp_path / "c.bin"
    assert main(["log", "--port", "delta6sim://?rate=1000", "-o", str(tmp_path / "l.csv"),
                 "--capture", str(capture), "--duration", "0.5"]) == 0
    capsys.readouterr()

    def full(fd, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("delta6.link.logfile.os.write", full)
    assert main(["decode", str(capture), "-o", str(tmp_path / "d.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No space left on device" in err
    assert not (tmp_path / "d.csv").exists()



def _read_cuts(partial, data: bytes, *, seed: int, count: int):
    """What a killed writer can leave, ``count`` random cuts of ``data`` written to
    ``partial``: yields (cut, log) for those that read; the others must be refused in one
    line."""
    for cut in sorted(random.Random(seed).sample(range(len(data)), count)):
        partial.write_bytes(data[:cut])
        try:
            yield cut, read_log(partial)
        except LogError as exc:
            assert "\n" not in str(exc)

def test_every_file_reader_survives_a_truncated_log(tmp_path, capsys):
    """What SIGKILL can leave: a .partial cut anywhere reads as its whole rows, or is refused
    in one line; never a traceback, never a cut number."""
    assert main(["log", "--port", "delta6sim://?rate=1000", "-o", str(tmp_path / "w.csv"),
                 "--raw", "--duration", "0.3"]) == 0
    text = (tmp_path / "w.csv").read_bytes()
    for cut, log in _read_cuts(tmp_path / "cut.csv.partial", text, seed=2, count=40):
        whole = text[:cut].rsplit(b"\n", 1)[0].decode()
        assert len(log) == sum(1 for ln in whole.splitlines() if ln and ln[0].isdigit())


def test_an_interrupted_tare_does_not_leave_the_device_busy(device):
    """SIGTERM during a tare of 65535 samples (over two minutes): one line, status 143, and the
    device is told to stop averaging; after SIGKILL, `tare --abort` frees it."""
    port, sent = device
    tare = delta6("tare", "--port", port, "--samples", "65535")
    wait_for_command(tare, sent, P.Command.TARE)   # then the tare is averaging on the device
    tare.send_signal(signal.SIGTERM)
    status, err = finish(tare)
    assert status == 143 and err.strip() == "delta6 tare: interrupted (SIGTERM)", err
    quick = delta6("tare", "--port", port, "--samples", "5", "--clear")
    assert finish(quick)[0] == 0
    killed = delta6("tare", "--port", port, "--samples", "65535")
    wait_for_command(killed, sent, P.Command.TARE)
    killed.send_signal(signal.SIGKILL)
    finish(killed)
    busy = delta6("tare", "--port", port, "--samples", "5")
    status, err = finish(busy)
    assert status == 2 and "still running (delta6 tare --abort stops it)" in err
    status, out = finish_out(delta6("tare", "--port", port, "--abort"))
    assert status == 0 and out.strip() == "stopped the averaging; nothing was changed"
    status, out = finish_out(delta6("tare", "--port", port, "--samples", "5"))
    assert status == 0 and out.startswith("tare over 5 samples: Fx")


def wait_for_command(proc: subprocess.Popen, sent: Path, command, timeout: float = 30.0) -> None:
    """Until the device has received ``command`` from ``proc`` (a frame with that type byte
    after what it had received when called): a fixed wait after opening the port is too short
    on a loaded machine."""
    received = received_file(sent)
    start = received.stat().st_size if received.exists() else 0
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        data = received.read_bytes()[start:] if received.exists() else b""
        frames = (cobs.decode(f) for f in data.split(b"\0")[:-1] if f)
        if any(f and f[0] == int(command) for f in frames):
            return
        time.sleep(0.02)
    raise AssertionError(f"{proc.args} never sent {command!r}")


def finish_out(proc: subprocess.Popen, timeout: float = 30.0) -> tuple[int, str]:
    out, _ = proc.communicate(timeout=timeout)
    return proc.returncode, out


def test_a_truncated_mcap_log_keeps_its_samples_before_the_cut(tmp_path):
    """What SIGKILL can leave of an MCAP log: a .partial file cut anywhere reads as the
    samples of its whole chunks, equal to the complete log's first rows, or is refused in one
    line; a cut file under its final name is refused (it did not end as a log ends)."""
    assert main(["log", "--port", "delta6sim://?rate=1000", "-o", str(tmp_path / "w.mcap"),
                 "--raw", "--duration", "0.5"]) == 0
    whole = read_log(tmp_path / "w.mcap")
    data = (tmp_path / "w.mcap").read_bytes()
    kept = []
    for _, log in _read_cuts(tmp_path / "cut.mcap.partial", data, seed=3, count=30):
        n = len(log.t)
        kept.append(n)
        np.testing.assert_array_equal(log.wrench, whole.wrench[:n])
        np.testing.assert_array_equal(log.theta, whole.theta[:n])
        np.testing.assert_array_equal(log.seq, whole.seq[:n])
    assert len(kept) > 20 and kept == sorted(kept) and kept[-1] > 0.9 * len(whole.t)
    (tmp_path / "cut.mcap").write_bytes(data[:len(data) // 2])
    with pytest.raises(LogError, match="ends inside a record") as err:
        read_log(tmp_path / "cut.mcap")
    assert "\n" not in str(err.value)


def test_a_truncated_mcap_log_keeps_rows_whose_optional_values_are_nan(tmp_path):
    """NaN in an optional column is data (no temperature sensor), not a cut: the rows before
    the cut are all kept."""
    from delta6.link.mcaplog import McapLogWriter
    path = tmp_path / "nan.mcap"
    writer = McapLogWriter(path, optional=("temp_c",))
    n = 40
    for block in range(4):
        t = (block * n + np.arange(n) + 1) * 0.004
        writer.write_block(t, np.full((n, 6), 0.01), np.ones((n, 6)), temp_c=np.full(n, np.nan))
    writer.flush()
    data = writer.partial.read_bytes()        # what a crash now would leave (no footer yet)
    writer.close()
    cut = tmp_path / "cut.mcap.partial"
    cut.write_bytes(data)
    log = read_log(cut, require_complete_rows=False)
    assert len(log.t) == 4 * n and np.isnan(log.temp_c).all()


def _log_under_a_file_limit(out, limit_bytes: int, *options: str):
    """``delta6 log`` from the simulated device in a process whose files may not grow beyond
    ``limit_bytes`` (Python turns the limit into EFBIG, as a full disk gives ENOSPC)."""
    import resource
    import subprocess
    import sys
    code = ("import sys; from delta6.cli import main; sys.exit(main(['log', '--port', "
            f"'delta6sim://?rate=1000', '-o', {str(out)!r}, *{list(options)!r}]))")

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, preexec_fn=limit)


def test_a_full_disk_ends_an_mcap_log_on_whole_chunks(tmp_path):
    """The same for an MCAP log (its writes go through a buffered file): one line naming the
    file and the rows it keeps, exactly the rows the file holds, and a file cut back to its
    last whole chunk."""
    out = tmp_path / "full.mcap"
    run = _log_under_a_file_limit(out, 150_000, "--raw", "--duration", "20")
    assert run.returncode == 2, run.stderr
    line = run.stderr.strip().splitlines()[-1]
    partial = tmp_path / "full.mcap.partial"
    assert f"cannot write {partial}: File too large; it keeps the " in line, line
    kept = int(line.split("it keeps the ")[1].split()[0])
    log = read_log(partial)
    # Every row the line counts, each whole (the reader drops rows whose topics a cut split).
    assert len(log) == kept > 100
    assert partial.stat().st_size < 150_000 and not out.exists()
    assert np.all(np.diff(log.t) > 0) and np.all(np.diff(log.seq) == 1)


def test_an_mcap_log_whose_header_does_not_fit_leaves_no_file(tmp_path):
    """A disk already full: one line naming the file, and no empty .partial left behind (the
    next log would have to be forced over it)."""
    out = tmp_path / "none.mcap"
    run = _log_under_a_file_limit(out, 200, "--duration", "1")
    assert run.returncode == 2, run.stderr
    err = run.stderr.strip().splitlines()
    assert len(err) == 1 and f"cannot write {out}.partial: File too large" in err[0], err
    assert list(tmp_path.iterdir()) == []
