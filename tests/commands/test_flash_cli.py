"""``delta6 flash``: the header and PlatformIO command it prepares, the board's answer checked
against the expected design hash, and one line with exit 2 for every way it can fail. A stand-in
``pio`` records its arguments (PlatformIO cannot download its platforms here)."""
from __future__ import annotations

import shlex

import pytest

from delta6.cli import main
from delta6.core.design import load

from conftest import DESIGNS


@pytest.fixture
def project(tmp_path):
    """A firmware project directory of our own: the checkout's header stays untouched."""
    fw = tmp_path / "firmware"
    fw.mkdir()
    (fw / "platformio.ini").write_text("[platformio]\n")
    return fw


def fake_pio(tmp_path, status=0):
    record = tmp_path / "pio-args.txt"
    script = tmp_path / "pio"
    script.write_text(f"#!/bin/sh\necho \"$@\" > {shlex.quote(str(record))}\nexit {status}\n")
    script.chmod(0o755)
    return script, record


def test_dry_run_prints_the_plan_and_changes_nothing(project, capsys):
    assert main(["flash", "--port", "/dev/ttyACM0", "--firmware-dir", str(project),
                 "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    h = load(DESIGNS / "delta6.toml").hash32()
    assert out[0].startswith(f"would write {project}/include/generated/delta6_design.h for design "
                             f"'delta6' (hash 0x{h:08x})")
    assert out[1] == (f"would run: pio run -d {project} -e nano_every -t upload "
                      "--upload-port /dev/ttyACM0")
    assert not (project / "include").exists()


def test_flash_writes_the_header_runs_pio_and_confirms_the_hash(project, tmp_path, capsys):
    pio, record = fake_pio(tmp_path)
    assert main(["flash", "--port", "delta6sim://", "--firmware-dir", str(project),
                 "--pio", str(pio)]) == 0
    assert record.read_text().split() == ["run", "-d", str(project), "-e", "nano_every", "-t",
                                          "upload", "--upload-port", "delta6sim://"]
    header = (project / "include" / "generated" / "delta6_design.h").read_text()
    h = load(DESIGNS / "delta6.toml").hash32()
    assert f"0x{h:08x}" in header.lower()
    assert capsys.readouterr().out.startswith(
        f"flashed: the board on delta6sim:// reports design 'delta6' (hash 0x{h:08x})")


def test_a_board_with_another_design_is_exit_2(project, tmp_path, capsys):
    pio, _ = fake_pio(tmp_path)
    status = main(["flash", "--port", "delta6sim://", "--design", str(DESIGNS / "stiff.toml"),
                   "--firmware-dir", str(project), "--pio", str(pio)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert "reports design 'delta6' (hash 0x535534af), expected design 'stiff'" in err[-1]


@pytest.mark.parametrize("case, message", [
    ("missing", "PlatformIO not found at"),
    ("no-path", "PlatformIO (pio) is not installed: pip install -e '.[firmware]'"),
    ("fails", "PlatformIO failed (exit status 3) running run -d"),
    ("silent", "did not answer within 0.3 s after flashing"),
    ("calibration", "--calibration: this firmware version builds in no calibration"),
])
def test_failures_are_one_line_and_exit_2(case, message, project, tmp_path, capsys, monkeypatch):
    pio, _ = fake_pio(tmp_path, status=3 if case == "fails" else 0)
    argv = ["flash", "--port", "delta6sim://", "--firmware-dir", str(project), "--pio", str(pio)]
    if case == "missing":
        argv[-1] = str(tmp_path / "nowhere" / "pio")
    elif case == "no-path":
        argv = argv[:-2]
        monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    elif case == "silent":
        argv[2] = str(tmp_path / "no-such-port")
        argv += ["--timeout", "0.3"]
    elif case == "calibration":
        argv += ["--calibration", "cal.toml"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and err[-1].startswith("delta6 flash: error: ")
