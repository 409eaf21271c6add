"""The solver on the AVR: the ATmega328P image built with Debian's avr-gcc and Arduino core,
run in simavr, computes what the reference computes; the portable core builds for avrxmega3
(the ATmega4809's instruction set); a design variant rebuilds with one command.

The cycle figures themselves are the benchmark's job (tools/bench_solver_avr.py); emulated
cycles are deterministic, so the requirement (<= 40,000 per solve) is also checked here.
"""
from __future__ import annotations

import subprocess

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.build import avrbuild
from delta6.cli import main
from delta6.core.calibrated import CalibratedModel
from delta6.core.design import load
from delta6.core.model import ENCODER_COUNT_RAD, wrench
from delta6.core.spec import full_scale
from delta6.sim import avrsim, solverbench, virtualboard
from delta6_codegen import render, render_calibration

from conftest import DESIGNS
from support.calibrations import random_calibration, with_curves

REQUIRED_CYCLES = 40_000
AVR_TOLERANCE_FS = 5e-4       # the required accuracy on the AVR: 0.05 % FS
FLOAT32_TOLERANCE_FS = 2e-6   # what float32 reaches natively; the AVR must match it


def check_against_reference(report, design):
    assert report.design_name == design.name
    assert report.design_hash == design.hash32()
    assert (report.status == 0).all()
    ref = wrench(design, report.delta * ENCODER_COUNT_RAD)
    err = (np.abs(report.wrench.astype(float) - ref) / full_scale(design)).max(axis=0)
    assert (err < AVR_TOLERANCE_FS).all(), err
    assert (err < FLOAT32_TOLERANCE_FS).all(), err
    return ref


def test_simulated_avr_matches_the_reference():
    run = solverbench.run_bench(avrbuild.COMMITTED_DESIGN_INCLUDE, solves=80,
                                name="test-solver-bench")
    design = load(DESIGNS / "delta6.toml")
    check_against_reference(run.report, design)
    lim = design.joint_limit_rad / ENCODER_COUNT_RAD
    assert (np.abs(run.report.delta[1:65]) == int(lim)).all()   # the 64 corners are covered
    assert len({tuple(r) for r in run.report.delta}) == 80
    assert run.cycles.max() <= REQUIRED_CYCLES
    assert run.cycles.min() > 1000                              # the markers bracket real work
    assert 0 < run.report.peak_stack < avrbuild.NANO.ram_bytes - run.report.static_ram


def test_a_variant_rebuilds_and_runs(tmp_path):
    """Another design's header in its own include directory: the AVR reports that design and
    computes its wrench, not the baseline's."""
    stiff = load(DESIGNS / "stiff.toml")
    include = tmp_path / "include"
    (include / "generated").mkdir(parents=True)
    (include / "generated" / "delta6_design.h").write_text(render(stiff, "designs/stiff.toml"))
    run = solverbench.run_bench(include, solves=24, name="test-solver-bench-stiff")
    ref = check_against_reference(run.report, stiff)
    baseline = wrench(load(DESIGNS / "delta6.toml"), run.report.delta * ENCODER_COUNT_RAD)
    assert np.abs(ref - baseline).max() > 1.0


def test_codegen_build_writes_the_header_and_the_image(tmp_path, capsys):
    header = tmp_path / "generated" / "delta6_design.h"
    assert main(["codegen", str(DESIGNS / "half-scale.toml"), "--build", "-o", str(header)]) == 0
    out = capsys.readouterr().out
    assert "half-scale" in header.read_text()
    elf = next(line.split()[1] for line in out.splitlines() if line.startswith("built "))
    assert elf.endswith(".elf") and "flash" in out


def test_codegen_build_default_leaves_the_committed_header_alone(capsys):
    committed = avrbuild.COMMITTED_DESIGN_INCLUDE / "generated" / "delta6_design.h"
    before = committed.read_bytes()
    assert main(["codegen", str(DESIGNS / "half-scale-stiff.toml"), "--build"]) == 0
    assert committed.read_bytes() == before
    written = avrbuild.design_include_dir("half-scale-stiff") / "generated" / "delta6_design.h"
    assert "half-scale-stiff" in written.read_text()


@pytest.mark.parametrize("mcu, flash, ram", [("avrxmega3", 48 * 1024, 6 * 1024),
                                             ("atmega328p", 32 * 1024, 2 * 1024)])
def test_portable_core_size(mcu, flash, ram):
    image = solverbench.build_probe(avrbuild.COMMITTED_DESIGN_INCLUDE, mcu)
    # The solver, its tables and the float routines: kilobytes, not an empty image.
    assert 4000 < image.sizes.flash < flash // 2
    assert image.sizes.ram < ram // 8


@given(st.binary(max_size=200))
def test_decoder_rejects_garbage_cleanly(data):
    try:
        report = solverbench.decode(data)
    except ValueError:
        return
    assert len(report.delta) == len(report.status) == len(report.wrench)


def frame(kind: str, *values) -> bytes:
    return bytes([solverbench.SYNC, ord(kind)]) + solverbench.FRAMES[ord(kind)].pack(*values)


def test_decoder_round_trip():
    solve = frame("S", 1, -2, 3, -4, 5, -6, 0, 1.5, -2.5, 0.0, 1e-3, 2e-3, -3e-3)
    report = solverbench.decode(frame("I", 0xABCD1234, 1, b"x") + solve + frame("E", 300, 250))
    assert report.design_name == "x" and report.design_hash == 0xABCD1234
    assert report.delta.tolist() == [[1, -2, 3, -4, 5, -6]]
    assert report.wrench[0, 1] == np.float32(-2.5) and report.peak_stack == 300
    with pytest.raises(ValueError, match="announced 2 solves"):
        solverbench.decode(frame("I", 1, 2, b"x") + solve + frame("E", 300, 250))
    with pytest.raises(ValueError, match="truncated"):
        solverbench.decode(frame("I", 1, 1, b"x") + solve[:-1])


def test_build_errors_name_the_problem(tmp_path):
    broken = tmp_path / "broken.cpp"
    broken.write_text("int main() { return undefined_name; }\n")
    with pytest.raises(avrbuild.BuildError, match="undefined_name"):
        avrbuild.build_image("broken", [broken], arduino=False)
    with pytest.raises(avrbuild.BuildError, match="not found"):
        avrbuild.build_image("missing", [tmp_path / "nope.cpp"])


def test_missing_toolchain_says_how_to_install(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(avrbuild.ToolchainMissing, match="apt-get install"):
        avrbuild.build_image("x", [solverbench.PROBE_SOURCE], arduino=False)


def test_simulator_reports_firmware_that_never_finishes():
    image = solverbench.build_bench_image(avrbuild.COMMITTED_DESIGN_INCLUDE, solves=4,
                                          name="test-unfinished")
    with pytest.raises(avrsim.SimulatorError, match="no stop marker"):
        avrsim.run(image.elf, max_cycles=100_000)


@pytest.mark.parametrize("tool", ["runner", "virtual_board"])
@pytest.mark.parametrize("args, message", [
    (["--bogus", "x.elf"], "unknown option --bogus"),
    (["x.elf", "--freq"], "--freq needs a value"),
    (["a.elf", "b.elf"], "more than one firmware file given"),
    ([], "no firmware file given"),
])
def test_the_c_harnesses_reject_bad_arguments_in_one_line(tool, args, message):
    """Both simavr programs parse options with getopt_long: a bad command line is one line on
    stderr and exit status 2, before any simulation starts."""
    exe = avrsim.harness() if tool == "runner" else virtualboard.harness()
    proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    words = message.split()
    assert all(w.strip(":") in proc.stderr for w in words), proc.stderr


def test_the_runner_takes_options_in_any_order_and_the_equals_form():
    image = solverbench.build_bench_image(avrbuild.COMMITTED_DESIGN_INCLUDE, solves=4,
                                          name="test-unfinished")
    for args in ([str(image.elf), "--max-cycles", "1000"],
                 ["--max-cycles=1000", str(image.elf)]):
        proc = subprocess.run([str(avrsim.harness()), *args], capture_output=True, text=True,
                              timeout=30)
        assert proc.returncode == 3, proc.stderr             # ran, hit the cycle limit


@pytest.mark.parametrize("seed,curved", [(5, False), (6, False), (7, True)])
def test_simulated_avr_calibrated_solver_matches_the_python_model(tmp_path, baseline, seed,
                                                                  curved):
    # The calibrated solver compiled for the ATmega328P, along the bench's random walk (history
    # included), against delta6.core.calibrated: the same 0.01 % FS as the native check; with
    # both curve tables, the curved solve's 16-bit products and fixed-point angle on the AVR.
    cal = random_calibration(baseline, seed)
    if curved:
        cal = with_curves(cal, seed)
    generated = tmp_path / "generated"
    generated.mkdir()
    (generated / "delta6_design.h").write_text(render(baseline, "designs/delta6.toml"))
    (generated / "delta6_calibration.h").write_text(
        render_calibration(baseline, cal, "designs/delta6.toml", "random.toml"))
    run = solverbench.run_bench(tmp_path, solves=200, name="calibrated-bench-test",
                                calibrated=True)
    report = run.report
    assert report.design_hash == baseline.hash32() and (report.status == 0).all()
    assert len(np.unique(report.delta, axis=0)) > 150     # a walk, not one pose
    python, _ = CalibratedModel(baseline, cal).run(report.delta.astype(float),
                                                   solverbench.CALIBRATED_PERIOD_S)
    err = np.abs(report.wrench.astype(float) - python) / full_scale(baseline) * 100
    assert err.max() < 0.01, err.max(axis=0)
