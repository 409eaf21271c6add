"""The sidecar truth file: what was simulated, exactly (docs/twin.md, "Truth file").

``data.csv`` gets ``data.truth.json`` next to it. A run can be reproduced from its truth file
alone (:func:`replay_arguments`): the effects are rebuilt from their recorded parameters, not
drawn again.
"""
from __future__ import annotations

import json
import os
from contextlib import contextmanager
from dataclasses import fields
from pathlib import Path

from delta6 import __version__
from delta6.core.design import DesignError, validate
from delta6.core.errors import UserError
from delta6.core.workspace import check_solvable
from delta6.twin.effects import Effect, effect_class
from delta6.twin.fields import FieldError, flag
from delta6.twin.measurement import Measurement
from delta6.twin.plant import check_oversample
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
            json.dump(truth, f, indent=1, allow_nan=False)   # NaN is no JSON: fail loudly
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
    """The recorded effects, each checked as ``--effect`` checks a request; a problem names
    the record (``effects[2] backlash: play_rad must lie in ...``)."""
    records = truth["effects"]
    if not isinstance(records, list):
        raise UserError(f"effects takes a list, got {records!r}")
    effects = []
    for i, rec in enumerate(records):
        with _field(f"effects[{i}]", sep=" "):
            if not isinstance(rec, dict):
                raise FieldError("", f"takes an effect record, got {rec!r}")
            effects.append(effect_class(rec["name"]).from_truth(rec))
            if rec["name"] in [e.NAME for e in effects[:-1]]:
                raise FieldError("", f"{rec['name']} is recorded twice (a run has each once)")
    return effects


def replay_arguments(truth: dict) -> dict:
    """Keyword arguments of ``simulate`` that reproduce the recorded run exactly (runs on the
    random trajectory only; a custom path is not recorded). Every setting is checked as the
    command line's are: a field missing, of the wrong type or out of range (a hand-edited
    file) is one line naming it, not a traceback, a NaN in the outputs or an invalid file."""
    with _field(""):
        return _replay_arguments(truth)


@contextmanager
def _field(where: str, sep: str = "."):
    """Problems raised inside as one :class:`UserError` naming the field under ``where``."""
    def name(field) -> str:
        return ".".join(filter(None, (where, str(field))))

    said = f"{where}{sep}" if where else ""
    try:
        yield
    except FieldError as exc:
        raise UserError(f"{name(exc.field)}: {exc.problem}") from None
    except KeyError as exc:
        raise UserError(f"field {name(exc.args[0])!r} is missing (not a complete truth "
                        "file)") from None
    except (UserError, DesignError) as exc:   # an effect's own check, a design's, a field's
        raise UserError(f"{said}{exc}") from None
    except (TypeError, ValueError, AttributeError) as exc:
        raise UserError(f"{name('') or 'a field'}: wrong type or value ({exc})") from None


def _settings(cls, record, where: str):
    """A settings dataclass from its truth record, checked; its own field names."""
    if not isinstance(record, dict):
        raise FieldError(where, f"takes a mapping, got {record!r}")
    unknown = sorted(set(record) - {f.name for f in fields(cls)})
    if unknown:
        raise FieldError(f"{where}.{unknown[0]}", "unknown field")
    settings = cls(**record)
    try:
        settings.check()
    except FieldError as exc:
        raise exc.under(where) from None
    return settings


def _replay_arguments(truth: dict) -> dict:
    if not isinstance(truth.get("trajectory"), dict):
        raise FieldError("trajectory", f"takes a mapping, got {truth['trajectory']!r}")
    if "custom" in truth["trajectory"]:
        raise UserError("the run used a custom path, which a truth file does not record")
    temperature = truth["temperature"]
    if not isinstance(temperature, dict):
        raise FieldError("temperature", f"takes a mapping, got {temperature!r}")
    temp = {k: v for k, v in temperature.items() if k != "recorded"}
    record, measured = truth["design"], truth["measurement"]
    with _field("design", sep=": "):
        design = validate({"name": record["name"], **record["parameters"]})
        check_solvable(design)
    with _field("measurement"):
        measurement = Measurement.from_dict(measured)
    scenario = truth["scenario"]
    if scenario is not None and not isinstance(scenario, str):   # a label: any text
        raise FieldError("scenario", f"takes a name or null, got {scenario!r}")
    return {
        "design": design,
        "effects": effects_from_truth(truth),
        "duration_s": truth["duration_s"], "rate_hz": truth["rate_hz"], "seed": truth["seed"],
        "trajectory": _settings(TrajectorySettings, truth["trajectory"], "trajectory"),
        "temperature": _settings(TemperatureSettings, temp, "temperature"),
        "measurement": measurement,
        "record_temp": flag("temperature.recorded", temperature["recorded"]),
        "oversample": check_oversample(truth["oversample"]),
        "scenario": scenario,
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
