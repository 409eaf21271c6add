"""The sidecar truth file: what was simulated, exactly (docs/twin.md, "Truth file").

``data.csv`` gets ``data.truth.json`` next to it. A run can be reproduced from its truth file
alone (:func:`replay_arguments`): the effects are rebuilt from their recorded parameters, not
drawn again.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from delta6 import __version__
from delta6.core.design import validate
from delta6.core.errors import UserError
from delta6.twin.effects import Effect, effect_class
from delta6.twin.measurement import Measurement
from delta6.twin.temperature import TemperatureSettings
from delta6.twin.trajectory import TrajectorySettings

SCHEMA = "delta6-twin-truth/1"
SUFFIX = ".truth.json"


def truth_path(log_path: str | Path) -> Path:
    """``data.csv`` -> ``data.truth.json`` (any other name gets the suffix appended)."""
    log_path = Path(log_path)
    stem = log_path.name[:-4] if log_path.name.lower().endswith(".csv") else log_path.name
    return log_path.with_name(stem + SUFFIX)


def build_truth(result, *, effects, seed, duration_s, rate_hz, oversample, scenario,
                trajectory, temperature: TemperatureSettings, measurement: Measurement,
                seconds: float) -> dict:
    d = result.design
    return {
        "schema": SCHEMA,
        "generator": f"delta6 {__version__} (delta6.twin.simulate)",
        "design": {"name": d.name, "hash": f"0x{d.hash32():08x}", "parameters": d.canonical()},
        "scenario": scenario,
        "seed": int(seed),
        "duration_s": float(duration_s),
        "rate_hz": float(rate_hz),
        "samples": len(result),
        "oversample": int(oversample),
        "trajectory": trajectory,
        "temperature": {**temperature.as_dict(), "recorded": result.temp_c is not None},
        "measurement": measurement.as_dict(),
        "effects": [e.to_truth() for e in effects],
        "analytical_error_pct_fs": result.gap(),
        "generation_s": round(seconds, 3),
    }


def write_truth(path: str | Path, truth: dict) -> Path:
    """Write atomically (temporary file, then rename)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".partial")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(truth, f, indent=1)
            f.write("\n")
        os.replace(tmp, path)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None
    return path


def read_truth(path: str | Path) -> dict:
    path = Path(path)
    try:
        truth = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except (OSError, ValueError) as exc:
        raise UserError(f"{path}: not a truth file ({exc})") from None
    if not isinstance(truth, dict) or truth.get("schema") != SCHEMA:
        raise UserError(f"{path}: not a {SCHEMA} file")
    return truth


def effects_from_truth(truth: dict) -> list[Effect]:
    return [effect_class(rec["name"]).from_truth(rec) for rec in truth["effects"]]


def replay_arguments(truth: dict) -> dict:
    """Keyword arguments of ``simulate`` that reproduce the recorded run exactly (runs on the
    random trajectory only; a custom path is not recorded). A field missing or of the wrong
    type (a hand-edited file) is one line naming it, not a traceback."""
    try:
        return _replay_arguments(truth)
    except KeyError as exc:
        raise UserError(f"field {exc.args[0]!r} is missing (not a complete truth file)") from None
    except (TypeError, ValueError, AttributeError) as exc:
        raise UserError(f"a field has the wrong type or value ({exc})") from None


def _replay_arguments(truth: dict) -> dict:
    if "custom" in truth["trajectory"]:
        raise UserError("the run used a custom path, which a truth file does not record")
    temp = {k: v for k, v in truth["temperature"].items() if k != "recorded"}
    design = validate({"name": truth["design"]["name"], **truth["design"]["parameters"]})
    return {
        "design": design,
        "effects": effects_from_truth(truth),
        "duration_s": truth["duration_s"], "rate_hz": truth["rate_hz"], "seed": truth["seed"],
        "trajectory": TrajectorySettings(**truth["trajectory"]),
        "temperature": TemperatureSettings(**temp),
        "measurement": Measurement.from_dict(truth["measurement"]),
        "record_temp": truth["temperature"]["recorded"],
        "oversample": truth["oversample"], "scenario": truth["scenario"],
    }


def same_unit(truth: dict, seed: int) -> dict:
    """``simulate`` arguments for the same unit as the recorded run (the same design, effects
    and parameters, the same rig) in a new run: ``seed`` draws a new trajectory, new noise and
    a new temperature history. The caller sets the duration and the rate."""
    args = replay_arguments(truth)
    for key in ("duration_s", "rate_hz", "seed"):
        del args[key]
    args["seed"] = seed
    return args


def without(truth: dict, names) -> dict:
    """``simulate`` arguments for the recorded run with some effects removed (same seed, same
    trajectory, same noise): the analytical model's error on that run is what is left when the
    removed effects are modelled perfectly (the "true shrink" of a diagnosis)."""
    names = set(names)
    unknown = names - {e["name"] for e in truth["effects"]}
    if unknown:
        raise UserError(f"the run has no effect {sorted(unknown)[0]!r}")
    args = replay_arguments(truth)
    args["effects"] = [e for e in args["effects"] if e.NAME not in names]
    return args
