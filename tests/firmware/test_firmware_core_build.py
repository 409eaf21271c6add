"""The protocol core is portable firmware: it builds warning-free for the AVRs with Debian's
avr-gcc 5.4, fits the ATmega328P comfortably, and survives a sanitizer-instrumented fuzz run
whose output the host decodes without a single bad frame."""
from __future__ import annotations

import subprocess

import pytest

from delta6.build import avrbuild, nativebuild
from delta6.link.decoder import StreamDecoder
from delta6.link.protocol import Status, WrenchRecord

#: Budgets on the ATmega328P (32 KB flash, 2 KB RAM) for the whole protocol core with its
#: wrench pipeline (low-pass filter, tool frame: tanf, sinf, cosf, and 180 bytes of filter
#: and tool state), float library included; the solver and the board layer need the rest
#: (tests/sim/test_firmware_app.py checks that the whole application fits).
FLASH_BUDGET = 16 * 1024
RAM_BUDGET = 900
PROGRAM = [nativebuild.FIRMWARE_NATIVE / "avr_footprint.cpp", *nativebuild.core_sources()]
INCLUDES = [nativebuild.FIRMWARE_CORE, avrbuild.COMMITTED_DESIGN_INCLUDE / "generated"]


@pytest.mark.avr
def test_core_builds_for_the_4809_instruction_set():
    """-mmcu=avrxmega3 (the Nano Every's ATmega4809), warnings as errors."""
    image = avrbuild.size_check("protocol_footprint_xmega3", PROGRAM, INCLUDES)
    assert 0 < image.sizes.flash <= FLASH_BUDGET


@pytest.mark.avr
def test_core_fits_the_atmega328p():
    image = avrbuild.build_image("protocol_footprint", PROGRAM, INCLUDES, arduino=False)
    assert image.sizes.flash <= FLASH_BUDGET, image.sizes
    assert image.sizes.ram <= RAM_BUDGET, image.sizes


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




@pytest.mark.avr
def test_the_avr_build_sends_the_same_bytes_as_the_native_build():
    """avr-gcc 5.4 and avr-libc's float on the emulated ATmega328P against host g++: the
    same session gives the same bytes, record for record: CRC, COBS, quantisation, tare."""
    from delta6.sim import avrsession as avr_session
    avr = avr_session.run_on_avr()
    native = avr_session.run_natively()
    assert avr.uart == native
    records = StreamDecoder().feed(avr.uart)
    data = [r for r in records if isinstance(r, WrenchRecord)]
    assert len(data) == 160 and sum(r.counts is not None for r in data) == 110
    assert all(r.status & Status.TARE_ACTIVE for r in data[-50:])   # tared
    spans = avr_session.cycles(avr)
    assert spans["stopped"] < spans["wrench"] < spans["raw"] < spans["raw_tared"]
