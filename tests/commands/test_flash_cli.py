"""``delta6 flash``: the headers and PlatformIO command it prepares, the board's answer checked
against the expected design, calibration and model hashes, and one line with exit 2 for every
way it can fail. A stand-in ``pio`` records its arguments (PlatformIO cannot download its
platforms here); tests/sim/test_flash_check.py checks the hashes of a calibrated board with a
model."""
from __future__ import annotations

import shlex

import pytest

from delta6.cli import main
from delta6.commands.codegen import generate_headers
from delta6.core.design import load

from conftest import DESIGNS
from support.onchip import calibration_and_model


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
    ("calibration", "cal.toml"),
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


@pytest.fixture(scope="module")
def onchip(tmp_path_factory):
    return calibration_and_model(load(DESIGNS / "delta6.toml"), tmp_path_factory.mktemp("onchip"))


def test_calibration_and_model_headers_are_codegens_and_the_board_must_report_them(
        project, tmp_path, capsys, onchip):
    """The three headers land where the nano_every build includes them, byte for byte what
    delta6 codegen writes but for the command their banners name; the simulated device
    carries neither calibration nor model, so the hash check refuses it in one line."""
    cal, cal_path, model, model_path = onchip
    pio, record = fake_pio(tmp_path)
    status = main(["flash", "--port", "delta6sim://", "--firmware-dir", str(project),
                   "--pio", str(pio), "--calibration", str(cal_path), "--model", str(model_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert record.read_text().split()[:5] == ["run", "-d", str(project), "-e", "nano_every"]
    generated = project / "include" / "generated"
    # The banners name the flash command that wrote them, as it can be run again.
    command = shlex.join(["delta6", "flash", "--port", "delta6sim://", "--design",
                          "designs/delta6.toml", "--calibration", str(cal_path.resolve()),
                          "--model", str(model_path.resolve()), "--firmware-dir",
                          str(project.resolve())])
    # The design header's names `delta6 codegen` writing it there: it is the same for every
    # calibration and model.
    design_command = shlex.join(["delta6", "codegen", "designs/delta6.toml", "-o",
                                 str((generated / "delta6_design.h").resolve())])
    want = generate_headers(DESIGNS / "delta6.toml", cal_path, model_path, command=command,
                            design_command=design_command)
    assert (generated / "delta6_design.h").read_text() == want.text
    assert (generated / "delta6_calibration.h").read_text() == want.cal_text
    assert (generated / "delta6_model.h").read_text() == want.model_text
    assert err[-1] == (
        "delta6 flash: error: the board on delta6sim:// reports no calibration, no model, "
        f"expected calibration '{cal.name}' (hash 0x{cal.hash32():08x}), model "
        f"'{model.name}' (hash 0x{model.hash32():08x}): the upload did not take, or another "
        "board answered")


def test_flashing_without_a_calibration_removes_the_last_ones_headers(project, tmp_path, capsys,
                                                                       onchip):
    _, cal_path, _, model_path = onchip
    pio, _ = fake_pio(tmp_path)
    main(["flash", "--port", "delta6sim://", "--firmware-dir", str(project), "--pio", str(pio),
          "--calibration", str(cal_path), "--model", str(model_path)])
    generated = project / "include" / "generated"
    assert (generated / "delta6_calibration.h").exists()
    capsys.readouterr()
    assert main(["flash", "--port", "delta6sim://", "--firmware-dir", str(project), "--dry-run"]) == 0
    plan = capsys.readouterr().out
    assert f"would remove {generated / 'delta6_calibration.h'}" in plan
    assert f"would remove {generated / 'delta6_model.h'}" in plan
    assert (generated / "delta6_calibration.h").exists()        # a dry run changes nothing
    assert main(["flash", "--port", "delta6sim://", "--firmware-dir", str(project),
                 "--pio", str(pio)]) == 0
    assert not (generated / "delta6_calibration.h").exists()
    assert not (generated / "delta6_model.h").exists()


def test_a_model_without_its_calibration_is_refused_before_anything_is_written(
        project, tmp_path, capsys, onchip):
    _, _, _, model_path = onchip
    pio, record = fake_pio(tmp_path)
    status = main(["flash", "--port", "delta6sim://", "--firmware-dir", str(project),
                   "--pio", str(pio), "--model", str(model_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("delta6 flash: error: ")
    assert not record.exists() and not (project / "include").exists()
