"""The protocol core is portable firmware: it builds warning-free for the AVRs with Debian's
avr-gcc 5.4, fits the ATmega328P comfortably, and survives a sanitizer-instrumented fuzz run
whose output the host decodes without a single bad frame."""
from __future__ import annotations

import subprocess

import pytest

from delta6 import nativebuild
from delta6.decoder import StreamDecoder
from delta6.protocol import WrenchRecord

#: Budgets on the ATmega328P (32 KB flash, 2 KB RAM) for the whole protocol core, float
#: library included; the solver and the board layer need the rest.
FLASH_BUDGET = 12 * 1024
RAM_BUDGET = 640
needs_avr = pytest.mark.skipif(nativebuild.AVR_CXX is None,
                               reason="avr-g++ missing: run tools/bootstrap.sh")


@needs_avr
@pytest.mark.parametrize("mcu", ["atmega328p", "avrxmega3"])
def test_core_compiles_for_the_avr(tmp_path, mcu):
    for src in nativebuild.core_sources():
        nativebuild.build_avr([src], tmp_path / (src.stem + ".o"), mcu=mcu, link=False)


@needs_avr
def test_core_fits_the_atmega328p(tmp_path):
    elf = nativebuild.build_avr([nativebuild.FIRMWARE_NATIVE / "avr_footprint.cpp",
                                 *nativebuild.core_sources()], tmp_path / "footprint.elf")
    fp = nativebuild.avr_size(elf)
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
