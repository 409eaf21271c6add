#!/usr/bin/env python3
"""Memory of every firmware image we ship, on the emulated ATmega328P (2 KB of RAM):

    .venv/bin/python tools/bench_ram.py                  # about a minute
    .venv/bin/python tools/bench_ram.py --calibration unit.toml --model model.json
    .venv/bin/python tools/bench_ram.py --symbols 12     # the largest RAM symbols of each

For the plain image (the analytical model), the calibrated one and the calibrated one with an
int8 residual model (without --calibration/--model: a calibration with every effect and a
small residual network over it, made here), it prints flash, static RAM (.data + .bss) and the
peak stack measured on the virtual board: the board boots from an erased EEPROM, answers
INFO, turns the whole wrench pipeline on (filter, tool frame, limits), saves the
configuration, streams wrench+raw records with the solver on a moving trajectory, and answers
INFO and TELEMETRY while it streams. simavr starts the SRAM zeroed, so the lowest non-zero
byte above the static data is as deep as the stack went (a lower bound, exact unless the
deepest bytes pushed were all zero). Also the avrxmega3 size check (the ATmega4809's
instruction set, 48 KB flash / 6 KB RAM) of each.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from delta6.build import appbuild, avrbuild
from delta6.commands.codegen import build_name, calibration_text, design_firmware, model_text
from delta6.core import calibration as C
from delta6.core import int8net, int8quant, residualmodel
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.learning import mcu
from delta6.link.device import Device
from delta6.sim.virtualboard import VirtualBoard, demo_trajectory, stack_depth, theta_to_counts, write_replay

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "designs" / "delta6.toml"


def made_calibration(design, path: Path) -> Path:
    """A calibration with every effect the calibrated model has (the memory does not depend
    on the values, only on which stages run)."""
    rng = np.random.default_rng(7)
    cal = C.neutral(design, "bench-unit").with_(
        offset_rad=rng.uniform(-0.01, 0.01, 6), backlash_play_rad=rng.uniform(0, 0.01, 6),
        direction_half_counts=3, rate_ratio=1.0 + rng.uniform(-0.1, 0.1, 6),
        hysteresis_radii_counts=(16, 64, 256), hysteresis_nm=rng.uniform(-0.01, 0.01, (6, 3)),
        speed_filter_s=0.02, friction_speeds_rad_s=(0.005, 0.02),
        friction_sign_nm=rng.uniform(-0.008, 0.008, (6, 2)),
        viscous_nm_s_per_rad=rng.uniform(-0.005, 0.005, 6),
        presliding_nm=rng.uniform(-0.003, 0.003, 6), delta_a_mm=rng.uniform(-0.5, 0.5, 3),
        delta_b_mm=rng.uniform(-0.5, 0.5, 3), delta_la_mm=rng.uniform(-0.5, 0.5, 3),
        delta_lb_mm=rng.uniform(-1, 1, 3), delta_azimuth_rad=rng.uniform(-0.01, 0.01, 3),
        delta_rest_angle_rad=rng.uniform(-0.01, 0.01, 3),
        gimbal_misalignment_rad=rng.uniform(-0.01, 0.01, 3),
        elbow_rad_per_nm=rng.uniform(0, 0.1, 3), tilt_rad_per_nm=0.05)
    return C.save(cal, path)


#: The largest model codegen takes over a calibration (MAX_MODEL_MACS: 24 inputs -> 6 = 144
#: multiply-accumulates) with the most state: the base wrench, the counts and two plays.
LARGEST_FEATURES = (int8quant.FeatureSpec("wrench"), int8quant.FeatureSpec("counts"),
                    int8quant.FeatureSpec("play", 4), int8quant.FeatureSpec("play", 16))


def made_model(design, cal_path: Path, path: Path) -> Path:
    """The largest network codegen takes over a calibration, with random weights, quantized
    over random feature values as training would."""
    cal = C.load(cal_path)
    rng = np.random.default_rng(5)
    scale = mcu.input_scale_for(design)
    counts = rng.integers(0, 16384, (400, 6))
    base = rng.normal(0, 5, (400, 6))
    v = int8net.feature_values(LARGEST_FEATURES, int8net.quantize_input(base, scale),
                               counts).astype(float)
    sizes = [v.shape[1], 6]
    net = int8quant.FloatNet(
        100.0, scale, LARGEST_FEATURES, 1.0 / np.maximum(v.std(axis=0), 1.0),
        tuple(rng.normal(0, 1 / np.sqrt(a), (b, a)) for a, b in zip(sizes, sizes[1:])),
        tuple(rng.normal(0, 0.1, b) for b in sizes[1:]), np.full(6, 0.01))
    model = residualmodel.ResidualModel(
        name="bench-residual", design_name=design.name, design_hash=design.hash32(),
        base="calibrated", net=int8quant.quantize(net, v), calibration_name=cal.name,
        calibration_hash=cal.hash32())
    return residualmodel.save(model, path)


def largest_ram_symbols(elf: Path, n: int) -> list[tuple[int, str]]:
    out = subprocess.run(["avr-nm", "-C", "-S", "-t", "d", "--size-sort", str(elf)],
                         capture_output=True, text=True, check=True).stdout
    rows = []
    for line in out.splitlines():
        parts = line.split(maxsplit=3)
        if len(parts) == 4 and parts[2] in "dDbB":
            rows.append((int(parts[1]), parts[3].replace("(anonymous namespace)::", "")))
    return sorted(rows, reverse=True)[:n]


def peak_stack(image: avrbuild.Image, seconds: float, tmp: Path) -> tuple[int, int]:
    """The deepest stack, and the rate streamed: the image's own rating with the pipeline on
    (INFO's max_rate_pipeline_hz)."""
    t, theta = demo_trajectory(duration_s=10.0, rate_hz=1000.0, amplitude=0.9)
    replay = write_replay(tmp / "motion.d6rp", t, theta_to_counts(theta))
    ram = tmp / "ram.bin"
    with VirtualBoard(image=image, replay=replay, loop=True, live=True, speed=0,
                      ram_dump=ram) as board:
        with Device(board.port, timeout=3.0) as dev:
            rate_hz = dev.info(refresh=True).max_rate_pipeline_hz
            dev.start(rate_hz)   # the pipeline is refused at a stream rate above its rating
            dev.stop()
            dev.set_filter(min(20.0, 0.2 * rate_hz))
            dev.set_tool((0.01, -0.02, 0.05), (0.1, -0.2, 0.3))
            dev.set_limits([20.0, 20.0, 30.0, 0.5, 0.5, 0.5])
            dev.save_config()
            dev.set_mode("raw")
            dev.start(rate_hz)
            end = board.live.time() + seconds
            while board.live.time() < end:
                dev.info(refresh=True)
                dev.telemetry()
                dev.flush()
            dev.stop()
        board.stop()
    return stack_depth(ram, image.sizes.ram), rate_hz


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calibration", type=Path, metavar="CAL.toml")
    parser.add_argument("--model", type=Path, metavar="MODEL.json",
                        help="a residual model over --calibration (needs it)")
    parser.add_argument("--seconds", type=float, default=2.0,
                        help="board seconds streamed per image (default 2)")
    parser.add_argument("--symbols", type=int, default=0, metavar="N",
                        help="also list the N largest RAM symbols of each image")
    args = parser.parse_args()
    if args.model is not None and args.calibration is None:
        parser.error("--model needs the --calibration it was trained over")
    design = load(DESIGN)
    with tempfile.TemporaryDirectory(prefix="delta6-bench-ram-") as tmp_name:
        tmp = Path(tmp_name)
        cal = args.calibration or made_calibration(design, tmp / "unit.toml")
        model = args.model or made_model(design, cal, tmp / "model.json")
        images = {"plain": (), "calibrated": (cal,), "calibrated+model": (cal, model)}
        total = avrbuild.NANO.ram_bytes
        print(f"{'image':<18} {'flash B':>8} {'.data':>6} {'.bss':>6} {'static':>7} "
              f"{'stack':>6} {'total':>6} of {total}   avrxmega3 flash/RAM   stream Hz")
        for name, extra in images.items():
            try:
                image = design_firmware(DESIGN, *extra)
            except avrbuild.BuildError as exc:
                overflow = [ln for ln in str(exc).splitlines() if "overflowed" in ln]
                print(f"{name:<18} does not link: {(overflow or ['build failed'])[0].strip()}")
                continue
            except UserError as exc:      # codegen refuses the model over this calibration
                print(f"{name:<18} refused: {exc}")
                continue
            stack, rate_hz = peak_stack(image, args.seconds, tmp)
            s = image.sizes
            cal_obj, _ = calibration_text(design, DESIGN, extra[0] if extra else None)
            model_obj, _ = model_text(design, DESIGN, extra[1] if len(extra) > 1 else None,
                                      cal_obj)
            include = avrbuild.design_include_dir(build_name(design, cal_obj, model_obj))
            probe = appbuild.size_check_app("avrxmega3", include_dir=include,
                                            name=f"delta6-ram-{name.replace('+', '-')}")
            print(f"{name:<18} {s.flash:>8} {s.data:>6} {s.bss:>6} {s.ram:>7} {stack:>6} "
                  f"{s.ram + stack:>6}      {probe.sizes.flash:>6} / {probe.sizes.ram:<6}"
                  f"    {rate_hz:>5}")
            for size, symbol in largest_ram_symbols(image.elf, args.symbols):
                print(f"    {size:>5}  {symbol}")
    print("stack: each image streams at its rated rate with the pipeline on, INFO and "
          "TELEMETRY answered meanwhile")
    return 0


if __name__ == "__main__":
    sys.exit(main())
