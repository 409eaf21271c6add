"""No command writes over a file it reads (or over a design shipped with delta6): one line,
exit 2, the input unchanged. (Each of these once replaced its input and exited 0.)"""
from __future__ import annotations

import shutil

import pytest

from delta6.cli import main
from delta6.core.paths import DEFAULT_DESIGN


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("spare")
    log = folder / "data.csv"
    assert main(["simulate", "--duration", "20", "--seed", "3", "-o", str(log)]) == 0
    design = folder / "d.toml"
    shutil.copy(DEFAULT_DESIGN, design)
    capture = folder / "cap.bin"
    capture.write_bytes(b"\x00" * 64)
    return folder, log, design, capture


CASES = {
    "diagnose --json": lambda f, log, d, cap: ["diagnose", str(log), "--json", str(log)],
    "calibrate -o": lambda f, log, d, cap: ["calibrate", str(log), "--design", str(d),
                                            "-o", str(log)],
    "calibrate -o the design": lambda f, log, d, cap: ["calibrate", str(log), "--design",
                                                       str(d), "-o", str(d)],
    "calibrate -o a shipped design": lambda f, log, d, cap: [
        "calibrate", str(log), "--design", str(d), "-o", str(DEFAULT_DESIGN)],
    "evaluate --json": lambda f, log, d, cap: ["evaluate", str(log), "--design", str(d),
                                               "--json", str(log)],
    "train -o": lambda f, log, d, cap: ["train", str(log), "--design", str(d), "--model",
                                        "mlp", "-o", str(log)],
    "decode -o": lambda f, log, d, cap: ["decode", str(cap), "-o", str(cap), "--force"],
    "simulate -o the unit": lambda f, log, d, cap: [
        "simulate", "--unit", str(f / "data.truth.json"), "-o", str(f / "data.truth.json")],
    "simulate's truth over the unit": lambda f, log, d, cap: [
        "simulate", "--unit", str(f / "data.truth.json"), "-o", str(f / "data.csv")],
    "virtual --stats": lambda f, log, d, cap: ["virtual", "--replay", str(log), "--stats",
                                               str(log)],
    "codegen -o": lambda f, log, d, cap: ["codegen", str(d), "-o", str(d)],
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_an_output_that_is_an_input_is_refused(files, case, capsys):
    folder, log, design, capture = files
    before = {p: p.read_bytes() for p in folder.iterdir()}
    shipped = DEFAULT_DESIGN.read_bytes()
    assert main(CASES[case](folder, log, design, capture)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("is the input" in err[0] or "shipped with delta6" in err[0]), err
    assert {p: p.read_bytes() for p in folder.iterdir()} == before
    assert DEFAULT_DESIGN.read_bytes() == shipped
