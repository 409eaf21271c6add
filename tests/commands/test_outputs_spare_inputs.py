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
    assert len(err) == 1 and any(w in err[0] for w in ("is the input", "shipped with delta6",
                                                        "would replace the --unit")), err
    assert {p: p.read_bytes() for p in folder.iterdir()} == before
    assert DEFAULT_DESIGN.read_bytes() == shipped


def test_two_outputs_on_one_new_file_are_refused(tmp_path, capsys):
    """--stats and --eeprom naming the same file that does not exist yet: the statistics
    would replace the EEPROM image."""
    image = tmp_path / "e.bin"
    assert main(["virtual", "--static", "--duration", "1", "--eeprom", str(image),
                 "--stats", str(image)]) == 2
    assert "is the --eeprom image too" in capsys.readouterr().err
    assert not image.exists()


def test_simulate_says_which_file_its_truth_would_replace(files, capsys):
    folder, log, design, capture = files
    assert main(["simulate", "--unit", str(folder / "data.truth.json"), "-o",
                 str(folder / "data.csv")]) == 2
    err = capsys.readouterr().err
    assert "its truth file" in err and "would replace the --unit file" in err


@pytest.mark.parametrize("url, words", [
    ("delta6sim://?motion=static&pose=nan,0,0,0,0,0", "pose takes finite numbers"),
    ("delta6sim://?encoder_fault=1:nan", "encoder_fault=nan is outside"),
    ("delta6sim://?encoder_fault=1:7", "encoder_fault=7.0 is outside"),
])
def test_a_simulated_device_url_with_bad_numbers_is_refused(url, words, capsys):
    assert main(["info", "--port", url]) == 2
    assert words in capsys.readouterr().err
