"""The protocol core is portable firmware: it builds warning-free for the AVRs with Debian's
avr-gcc 5.4, fits the ATmega328P comfortably, and survives a sanitizer-instrumented fuzz run
whose output the host decodes without a single bad frame."""
from __future__ import annotations

import shutil
import subprocess

import pytest

from delta6 import nativebuild
from delta6.decoder import StreamDecoder
from delta6.protocol import WrenchRecord

AVR_GXX = shutil.which("avr-g++")
AVR_FLAGS = ["-Os", "-std=gnu++14", "-Wall", "-Wextra", "-Werror", "-fno-exceptions",
             "-fno-rtti", "-fno-threadsafe-statics", "-ffunction-sections", "-fdata-sections"]
#: Budgets on the ATmega328P (32 KB flash, 2 KB RAM) for the whole protocol core, float
#: library included; the solver and the board layer need the rest.
FLASH_BUDGET = 12 * 1024
RAM_BUDGET = 640
needs_avr = pytest.mark.skipif(AVR_GXX is None, reason="avr-g++ missing: run tools/bootstrap.sh")


@needs_avr
@pytest.mark.parametrize("mcu", ["atmega328p", "avrxmega3"])
def test_core_compiles_for_the_avr(tmp_path, mcu):
    for src in nativebuild.core_sources():
        proc = subprocess.run([AVR_GXX, f"-mmcu={mcu}", *AVR_FLAGS, "-c", str(src), "-o",
                               str(tmp_path / (src.stem + ".o"))], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def avr_footprint(out_dir) -> dict:
    elf = out_dir / "footprint.elf"
    cmd = [AVR_GXX, "-mmcu=atmega328p", *AVR_FLAGS, "-Wl,--gc-sections",
           f"-I{nativebuild.FIRMWARE_CORE}", str(nativebuild.FIRMWARE_NATIVE / "avr_footprint.cpp"),
           *map(str, nativebuild.core_sources()), "-o", str(elf)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    size = subprocess.run(["avr-size", str(elf)], capture_output=True, text=True, check=True)
    text, data, bss = map(int, size.stdout.splitlines()[1].split()[:3])
    return {"flash": text + data, "ram": data + bss}


@needs_avr
def test_core_fits_the_atmega328p(tmp_path):
    fp = avr_footprint(tmp_path)
    assert fp["flash"] <= FLASH_BUDGET, fp
    assert fp["ram"] <= RAM_BUDGET, fp


@pytest.fixture(scope="module")
def fuzzer():
    return nativebuild.build_executable(
        "fuzz_device_asan", [nativebuild.FIRMWARE_NATIVE / "fuzz_device.cpp",
                             *nativebuild.core_sources()],
        [nativebuild.FIRMWARE_CORE, nativebuild.FIRMWARE_NATIVE],
        flags=("-O1", "-g", "-fno-omit-frame-pointer", "-fsanitize=address,undefined",
               "-fno-sanitize-recover=all"))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sanitized_fuzz_run_is_clean_and_its_output_decodes(fuzzer, seed):
    proc = subprocess.run([str(fuzzer), str(seed), "100000"], capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr.decode(errors="replace")[-3000:]
    assert b"0 violations" in proc.stderr
    decoder = StreamDecoder()
    records = decoder.feed(proc.stdout)
    s = decoder.stats
    assert s.errors == 0 and s.resyncs == 0 and s.unknown_types == 0 and s.startup_bytes == 0
    assert decoder.pending_bytes == 0
    assert sum(isinstance(r, WrenchRecord) for r in records) > 5000
