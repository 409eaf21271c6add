"""The firmware application builds: the ATmega328P image fits its chip, the portable part fits
the ATmega4809's instruction set, PlatformIO points at the application, and a design variant
gets its own image that reports itself and computes its own model."""
from __future__ import annotations

import configparser
import re
import subprocess

import numpy as np

from delta6.build import appbuild, avrbuild
from delta6.commands.codegen import design_firmware
from delta6.core.design import load
from delta6.core.model import wrench as model_wrench
from delta6.link import protocol as P
from delta6.link.device import Device
from delta6.sim.virtualboard import VirtualBoard, stack_depth, theta_to_counts, write_replay

from conftest import DESIGNS, ROOT


def test_application_image_fits_the_atmega328p_with_room_for_its_stack():
    image = appbuild.build_app()
    assert 12_000 < image.sizes.flash <= avrbuild.NANO.flash_bytes
    # The benchmark measures about 320 B of stack; keep at least 450 B for it.
    assert image.sizes.ram + 450 <= avrbuild.NANO.ram_bytes


def test_portable_part_fits_the_atmega4809_instruction_set():
    image = appbuild.size_check_app("avrxmega3")
    assert 10_000 < image.sizes.flash < 48 * 1024 // 2
    assert image.sizes.ram < 6 * 1024 // 4


def test_the_application_uses_the_parallel_bus_not_digitalwrite():
    image = appbuild.build_app()
    symbols = subprocess.run(["avr-nm", "-C", str(image.elf)], capture_output=True,
                             text=True, check=True).stdout
    assert "digitalWrite" not in symbols and "HardwareSerial" not in symbols
    defined = {line.split()[2] for line in symbols.splitlines()
               if len(line.split()) == 3 and line.split()[1] == "T"}
    # TIMER1_COMPA (the sampling timer), USART_RX and USART_UDRE: our own interrupt handlers.
    assert {"__vector_11", "__vector_18", "__vector_19"} <= defined


def test_platformio_ini_declares_both_boards_and_the_application_sources():
    """What can be checked here: the configuration (PlatformIO's own build needs a platform
    download)."""
    ini = configparser.ConfigParser(interpolation=None)
    ini.read(ROOT / "firmware" / "platformio.ini")
    assert ini["platformio"]["default_envs"] == "nano_every"
    assert "src_dir" not in ini["platformio"]       # the default, firmware/src
    every, nano = ini["env:nano_every"], ini["env:nanoatmega328"]
    assert (every["platform"], every["board"]) == ("atmelmegaavr", "nano_every")
    assert (nano["platform"], nano["board"]) == ("atmelavr", "nanoatmega328")
    assert ini["env"]["framework"] == "arduino"
    assert "AVR_NANO_4809_328MODE" in every["build_unflags"]
    sources = {p.name for p in (ROOT / "firmware" / "src").glob("*.cpp")}
    assert {"main.cpp", "app.cpp", "board_atmega4809.cpp", "board_atmega328p.cpp"} <= sources


def test_the_firmware_docs_name_real_sections_and_the_pinned_platformio():
    """platformio.ini points to a section of docs/firmware.md that exists, and the PlatformIO
    version the docs checked the file with is the one the firmware extra pins."""
    ini = (ROOT / "firmware" / "platformio.ini").read_text()
    doc = (ROOT / "docs" / "firmware.md").read_text()
    headings = {line.lstrip("#").strip() for line in doc.splitlines() if line.startswith("#")}
    cited = re.findall(r'docs/firmware\.md, "([^"]+)"', ini)
    assert cited and set(cited) <= headings
    pinned = re.search(r'"platformio==([0-9.]+)"', (ROOT / "pyproject.toml").read_text())[1]
    said = re.findall(r"\(PlatformIO ([0-9.]+)", doc)
    assert said and set(said) == {pinned}


def test_a_design_variant_runs_its_own_model(tmp_path):
    stiff = load(DESIGNS / "stiff.toml")
    image = design_firmware(DESIGNS / "stiff.toml")
    assert image.elf.parent == avrbuild.design_build_dir("stiff") / "atmega328p"
    pose = np.array([0.1, -0.05, 0.08, 0.12, -0.1, 0.05])
    replay = write_replay(tmp_path / "pose.d6rp", [0.0], theta_to_counts(pose)[None])
    with VirtualBoard(image=image, replay=replay, speed=0, ram_dump=tmp_path / "ram") as board:
        with Device(board.port) as dev:
            info = dev.info()
            dev.set_mode("raw")
            dev.start(100)
            sample = dev.get(timeout=10)
            sample = dev.get(timeout=10)
    assert info.design_name == "stiff" and info.design_hash == stiff.hash32()
    ref = model_wrench(stiff, P.counts_to_theta(sample.counts, 0))
    assert np.all(np.abs(sample.wrench - ref) <= np.asarray(info.lsb) / 2 + 1e-5)
    assert np.abs(ref - model_wrench(load(DESIGNS / "delta6.toml"), pose)).max() > 0.1
    assert 100 < stack_depth(tmp_path / "ram", image.sizes.ram) < 600
