"""``delta6 info``: what the device is and how it is configured."""
from __future__ import annotations

import argparse
import json

from delta6.commands._port import AXES, add_port_arguments, flag_names, open_device
from delta6.link.protocol import Mode, Status, link_rate_limit

NAME = "info"
HELP = "print the device's identity, scaling, configuration and health"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print JSON")


def run(args: argparse.Namespace) -> int:
    with open_device(args) as dev:
        info = dev.info()
        rtt, _ = dev.ping()
        telemetry = dev.telemetry()
    if args.json:
        out = {**info._asdict(), "lsb": list(info.lsb), "ping_s": rtt,
               "telemetry": telemetry._asdict()}
        print(json.dumps(out, indent=2))
        return 0
    unit = ("N",) * 3 + ("N*m",) * 3
    lines = [
        f"Delta6 on {args.port}: design '{info.design_name}' (hash 0x{info.design_hash:08x}), "
        f"firmware {info.firmware_version}, protocol {info.protocol_version}, "
        f"serial 0x{info.serial_number:08x}",
        (f"  calibration '{info.calibration_name}' (hash 0x{info.calibration_hash:08x})"
         if info.calibration_hash else "  no calibration: the analytical model"),
        f"  rate {info.rate_hz} Hz (board max {info.max_rate_hz} Hz; link at {info.baud} baud "
        f"carries {link_rate_limit(info.baud, Mode.WRENCH)} Hz wrench, "
        f"{link_rate_limit(info.baud, Mode.WRENCH_RAW)} Hz wrench+raw)",
        f"  mode {Mode(info.mode).name.lower()}, {'streaming' if info.streaming else 'stopped'}, "
        f"status {flag_names(info.status, quiet=0)}, ping {rtt * 1e3:.1f} ms",
        "  axis  full scale      LSB        tare",
    ]
    for i, axis in enumerate(AXES):
        lines.append(f"  {axis:<4} {info.full_scale[i]:>9.4g} {unit[i]:<4} {info.lsb[i]:>8.3g} "
                     f"{info.tare[i]:>+11.5g}")
    lines.append("  zero counts " + " ".join(str(c) for c in info.zero_counts)
                 + f"; joint limit {info.joint_limit_rad:.4f} rad")
    t = telemetry
    lines.append(f"  health: {t.samples} samples, {t.overruns} overruns, "
                 f"encoder errors {list(t.encoder_errors)}, {t.solver_errors} solver errors, "
                 f"{t.tx_dropped} tx drops, {t.rx_crc_errors} bad commands, loop "
                 f"{t.loop_time_mean_us}/{t.loop_time_max_us} us mean/max"
                 + (f", {t.temperature_c:.1f} degC" if t.temperature_c is not None else ""))
    if info.status & Status.CONFIG_DEFAULTS:
        lines.append("  note: the EEPROM holds no valid configuration; defaults are in use "
                     "(delta6 tare --save, or Device.save_config(), stores one)")
    print("\n".join(lines))
    return 0
