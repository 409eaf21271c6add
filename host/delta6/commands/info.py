"""``delta6 info``: what the device is and how it is configured."""
from __future__ import annotations

import argparse
import json

from delta6.commands._port import AXES, add_port_arguments, flag_names, open_device
from delta6.commands.config import pipeline_lines
from delta6.link.protocol import ConfigProblem, Mode, Status, config_problem_text, link_rate_limit

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
    # Why the EEPROM configuration was rejected at boot (a protocol 1.0 board says 0: unknown),
    # or that it loaded with its rate lowered.
    lowered = info.config_problem == ConfigProblem.RATE_LOWERED
    problem = (config_problem_text(info.config_problem)
               if (info.status & Status.CONFIG_DEFAULTS and info.config_problem) or lowered
               else None)
    if args.json:
        # No sentinels in JSON: an unknown temperature is null, not 32767; no limit is null.
        health = {**telemetry._asdict(), "temperature_c": telemetry.temperature_c}
        if telemetry.temperature_c is None:
            health["temperature_centi"] = None
        out = {**info._asdict(), "lsb": list(info.lsb),
               "limit_values": [None if v != v else v for v in info.limit_values],
               "ping_s": rtt, "telemetry": health, "config_problem_text": problem}
        print(json.dumps(out, indent=2, allow_nan=False))
        return 0
    unit = ("N",) * 3 + ("N*m",) * 3
    lines = [
        f"Delta6 on {args.port}: design '{info.design_name}' (hash 0x{info.design_hash:08x}), "
        f"firmware {info.firmware_version}, protocol {info.protocol_version}, "
        f"serial 0x{info.serial_number:08x}",
        (f"  calibration '{info.calibration_name}' (hash 0x{info.calibration_hash:08x})"
         if info.calibration_hash else "  no calibration: the analytical model"),
        (f"  on-chip residual model '{info.model_name}' (hash 0x{info.model_hash:08x})"
         if info.model_hash else "  no on-chip residual model"),
        f"  rate {info.rate_hz} Hz (board max {info.max_rate_hz} Hz"
        + (f", {info.max_rate_pipeline_hz} Hz with the filter or tool frame on"
           if info.max_rate_pipeline_hz and info.max_rate_pipeline_hz < info.max_rate_hz else "")
        + f"; link at {info.baud} baud "
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
    lines += pipeline_lines(info)
    t = telemetry
    lines.append(f"  health: {t.samples} samples, {t.overruns} overruns, "
                 f"encoder errors {list(t.encoder_errors)}, {t.solver_errors} solver errors, "
                 f"{t.tx_dropped} tx drops, {t.rx_crc_errors} bad commands, loop "
                 f"{t.loop_time_mean_us}/{t.loop_time_max_us} us mean/max"
                 + (f", {t.temperature_c:.1f} degC" if t.temperature_c is not None else ""))
    if info.status & Status.CONFIG_DEFAULTS:
        why = f" ({problem})" if problem else ""
        lines.append(f"  note: the EEPROM holds no valid configuration{why}; defaults are in use "
                     "(delta6 tare --save, or Device.save_config(), stores one)")
    elif lowered:
        lines.append(f"  note: the EEPROM configuration was {problem}")
    print("\n".join(lines))
    return 0
