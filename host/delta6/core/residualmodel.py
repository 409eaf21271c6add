"""The on-chip residual model file: a quantized network with what it was trained for.

``delta6 train --target mcu -o MODEL.json`` writes it (and the float network as MODEL.onnx next
to it, for comparison); ``delta6 codegen --model MODEL.json`` turns it into the firmware header;
``delta6 evaluate --model MODEL.json`` runs it through the integer reference. JSON, schema
``delta6-residual-model/1``:

    {"schema": ..., "name": "paper-unit", "design": {"name", "hash": "0x..."},
     "base": "analytical" | "calibrated", "calibration": {"name", "hash"} | null,
     "network": {"rate_hz", "input_scale": [6], "output_step": [6],
                 "features": [{"kind", "param", "multiplier": [6], "shift": [6]}, ...],
                 "layers": [{"weights": [[...]], "bias", "multiplier", "shift", "relu"}, ...]},
     "training": {...}}          # how it was made and what it scored; not part of the hash

``hash32`` identifies the model the board runs (everything but ``training``); the device info
reports it.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from delta6.core.design import MAX_NAME_CHARS, label_problem, name_problem
from delta6.core.errors import UserError
from delta6.core.hashes import parse_hash32
from delta6.core.int8net import Feature, Int8Net, Layer

SCHEMA = "delta6-residual-model/1"
BASES = ("analytical", "calibrated")
MAX_NAME = MAX_NAME_CHARS


class ModelFileError(UserError):
    """A model file that cannot be read or is not a valid residual model."""


@dataclass(frozen=True)
class ResidualModel:
    name: str
    design_name: str
    design_hash: int
    base: str                               # "analytical" or "calibrated"
    net: Int8Net
    calibration_name: str | None = None
    calibration_hash: int | None = None
    training: dict = field(default_factory=dict)

    def identity(self) -> dict:
        """Everything the board's behaviour depends on, as JSON-ready data."""
        n = self.net
        return {
            "name": self.name,
            "design": {"name": self.design_name, "hash": f"0x{self.design_hash:08x}"},
            "base": self.base,
            "calibration": None if self.calibration_hash is None else {
                "name": self.calibration_name, "hash": f"0x{self.calibration_hash:08x}"},
            "network": {
                "rate_hz": float(n.rate_hz),
                "input_scale": [float(x) for x in n.input_scale],
                "output_step": [float(x) for x in n.output_step],
                "features": [{"kind": f.kind, "param": int(f.param),
                              "multiplier": [int(x) for x in f.multiplier],
                              "shift": [int(x) for x in f.shift]} for f in n.features],
                "layers": [{"weights": layer.weights.astype(int).tolist(),
                            "bias": layer.bias.astype(int).tolist(),
                            "multiplier": layer.multiplier.astype(int).tolist(),
                            "shift": layer.shift.astype(int).tolist(),
                            "relu": bool(layer.relu)} for layer in n.layers],
            },
        }

    def hash32(self) -> int:
        text = json.dumps(self.identity(), sort_keys=True, separators=(",", ":"))
        return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big")


#: The largest on-chip model (multiply-accumulates per sample) measured to hold the model
#: image's rated 200 Hz on the ATmega328P at 16 MHz, over each base (docs/ondevice-model.md:
#: the analytical default, 672, at 74,300 cycles of work per 80,000-cycle period; over a
#: calibration, whose solve took 51,000 then (49,000 now), the 144-MAC network at 75,400).
#: Over a calibration with curve tables (about 2,200 cycles and 1,560 B more), the default
#: linear map of the counts, 36: 65,000 cycles a sample and 32,240 B of the emulated
#: ATmega328P's 32 KB (flash holds it there: a 108-MAC network reading the wrench overflows).
MAX_MODEL_MACS = {"analytical": 672, "calibrated": 144, "calibrated with curves": 36}


def planned_macs(inputs: int, hidden: tuple[int, ...]) -> int:
    """Multiply-accumulates per sample of a network with ``inputs`` inputs, the ``hidden``
    layer widths and six outputs (what :attr:`Int8Net.macs` will count)."""
    widths = (inputs, *hidden, 6)
    return sum(a * b for a, b in zip(widths[:-1], widths[1:]))


def cost_limit(design, calibration=None) -> tuple[int, str]:
    """The largest model (multiply-accumulates) the firmware over this base runs at its rated
    rate, and the base as a phrase for messages."""
    from delta6.core import curves
    if calibration is None:
        return MAX_MODEL_MACS["analytical"], "the analytical model"
    if curves.has_curves(design, calibration):
        return MAX_MODEL_MACS["calibrated with curves"], "a calibration with curve tables"
    return MAX_MODEL_MACS["calibrated"], "the calibrated model"


def check_cost(macs: int, design, calibration=None, source: str = "the model") -> None:
    """Refuse a model no firmware image over this base runs at its rated 200 Hz."""
    limit, over = cost_limit(design, calibration)
    if macs > limit:
        raise UserError(f"{source}: {macs} multiply-accumulates per sample; over {over} the "
                        f"board keeps its 200 Hz with at most {limit} (train a smaller one: "
                        "--hidden)")


def check_base(model: ResidualModel, design, calibration=None) -> None:
    """The model must correct what runs under it: ``design``'s analytical wrench without a
    calibration, the calibrated wrench of that very calibration with one (one line, else)."""
    if model.design_hash != design.hash32():
        raise UserError(f"model '{model.name}' was trained for design '{model.design_name}' "
                        f"(hash 0x{model.design_hash:08x}), not '{design.name}' "
                        f"(0x{design.hash32():08x})")
    if model.base == "analytical":
        if calibration is not None:
            raise UserError(f"model '{model.name}' corrects the analytical model, not calibration "
                            f"'{calibration.name}'; train it with --residual-over the "
                            "calibration, or leave --calibration out")
        return
    trained_over = f"calibration '{model.calibration_name}' (hash 0x{model.calibration_hash:08x})"
    if calibration is None:
        raise UserError(f"model '{model.name}' corrects {trained_over}; give it with "
                        "--calibration")
    if model.calibration_hash != calibration.hash32():
        raise UserError(f"model '{model.name}' was trained over {trained_over}, not calibration "
                        f"'{calibration.name}' (hash 0x{calibration.hash32():08x})")


def dumps(model: ResidualModel) -> str:
    body = {"schema": SCHEMA, **model.identity(), "training": model.training}
    return json.dumps(body, indent=1) + "\n"


def save(model: ResidualModel, path: str | Path) -> Path:
    path = Path(path)
    tmp = path.with_name(path.name + ".partial")
    try:
        tmp.write_text(dumps(model), encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        raise ModelFileError(f"cannot write {path}: {exc.strerror}") from None
    return path


def _hex32(value, what: str, source: str) -> int:
    try:
        return parse_hash32(value)
    except ValueError as exc:
        raise ModelFileError(f"{source}: {what} {exc}") from None


def _holds_bool(values) -> bool:
    return isinstance(values, bool) or (isinstance(values, list)
                                        and any(_holds_bool(v) for v in values))


def _ints(values, dtype, what: str, source: str) -> np.ndarray:
    if _holds_bool(values):     # numpy would read true as 1 beside integers
        raise ModelFileError(f"{source}: {what} must hold integers, not true or false")
    try:
        array = np.asarray(values)
    except ValueError:      # ragged rows
        raise ModelFileError(f"{source}: {what} must be a rectangular table of integers") from None
    if array.dtype.kind not in "iu" or array.size == 0:
        raise ModelFileError(f"{source}: {what} must hold integers")
    info = np.iinfo(dtype)
    if array.min() < info.min or array.max() > info.max:
        raise ModelFileError(f"{source}: {what} out of range for {np.dtype(dtype).name}")
    return array.astype(dtype)


def _int(value, what: str, source: str) -> int:
    """A JSON integer: 4.7, "4" and true are refused, not turned into 4 or 1."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ModelFileError(f"{source}: {what} must be an integer, got {value!r}")
    return value


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _number(value, what: str, source: str) -> float:
    """A JSON number (strings and booleans refused) as a float."""
    if not _is_number(value):
        raise ModelFileError(f"{source}: {what} must be a number, got {value!r}")
    try:
        return float(value)
    except OverflowError:   # a JSON integer beyond any float (10**400)
        raise ModelFileError(f"{source}: {what} out of range") from None


def _numbers(values, what: str, source: str) -> np.ndarray:
    """Six JSON numbers as float32 (a value beyond float32 becomes inf: check() says so)."""
    if not isinstance(values, list) or len(values) != 6 or not all(map(_is_number, values)):
        raise ModelFileError(f"{source}: {what} must be six numbers")
    floats = [_number(v, what, source) for v in values]
    with np.errstate(over="ignore"):
        return np.asarray(floats, dtype=np.float32)


def _object(value, keys: tuple[str, ...], what: str, source: str,
            optional: tuple[str, ...] = ()) -> dict:
    """A JSON object holding ``keys`` (and perhaps ``optional``), nothing else: like a design
    or calibration file, an unknown key is refused by name (a typo is not silently ignored)."""
    if not isinstance(value, dict):
        raise ModelFileError(f"{source}: {what} must be a JSON object")
    for key in value:
        if key not in keys + optional:
            raise ModelFileError(f"{source}: unknown key '{key}' in {what} (expected "
                                 f"{', '.join(keys + optional)})")
    for key in keys:
        if key not in value:
            raise ModelFileError(f"{source}: {what} has no '{key}'")
    return value


def _name(value, what: str, source: str, rule=label_problem) -> str:
    """A model's or calibration's name is a label; a design's follows the design name rule."""
    problem = rule(value)
    if problem:
        raise ModelFileError(f"{source}: {what} {problem}")
    return value


_TOP_KEYS = ("schema", "name", "design", "base", "calibration", "network")
_NETWORK_KEYS = ("rate_hz", "input_scale", "output_step", "features", "layers")
_FEATURE_KEYS = ("kind", "param", "multiplier", "shift")
_LAYER_KEYS = ("weights", "bias", "multiplier", "shift", "relu")


def _layer(raw, i: int, source: str) -> Layer:
    what = f"layer {i + 1}"
    raw = _object(raw, _LAYER_KEYS, what, source)
    weights = _ints(raw["weights"], np.int8, f"{what} weights", source)
    if weights.ndim != 2:
        raise ModelFileError(f"{source}: {what} weights must be a matrix")
    if not isinstance(raw["relu"], bool):
        raise ModelFileError(f"{source}: {what} relu must be true or false")
    return Layer(weights, _ints(raw["bias"], np.int32, f"{what} bias", source),
                 _ints(raw["multiplier"], np.int16, f"{what} multiplier", source),
                 _ints(raw["shift"], np.uint8, f"{what} shift", source), raw["relu"])


def _feature(raw, i: int, source: str) -> Feature:
    what = f"feature {i + 1}"
    raw = _object(raw, _FEATURE_KEYS, what, source)
    if not isinstance(raw["kind"], str):
        raise ModelFileError(f"{source}: {what} kind must be a string")
    return Feature(raw["kind"], _int(raw["param"], f"{what} param", source),
                   tuple(_ints(raw["multiplier"], np.int16, f"{what} multiplier",
                               source).tolist()),
                   tuple(_ints(raw["shift"], np.uint8, f"{what} shift", source).tolist()))


def _list(value, what: str, source: str) -> list:
    if not isinstance(value, list):
        raise ModelFileError(f"{source}: {what} must be a list")
    return value


def loads(text: str, source: str = "model") -> ResidualModel:
    """Parse and validate; any problem is one ModelFileError line naming it."""
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise ModelFileError(f"{source}: not a residual model file (not JSON: {exc})") from None
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise ModelFileError(f"{source}: not a {SCHEMA} file")
    data = _object(data, _TOP_KEYS, "the model", source, optional=("training",))
    name = _name(data["name"], "name", source)
    base = data["base"]
    if base not in BASES:
        raise ModelFileError(f"{source}: base must be one of {', '.join(BASES)}")
    design = _object(data["design"], ("name", "hash"), "design", source)
    cal = data["calibration"]
    if (cal is None) != (base == "analytical"):
        raise ModelFileError(f"{source}: a model over the calibrated model names its "
                             "calibration, one over the analytical model none")
    if cal is not None:
        cal = _object(cal, ("name", "hash"), "calibration", source)
    training = data.get("training", {})
    if not isinstance(training, dict):
        raise ModelFileError(f"{source}: training must be a JSON object")
    net_data = _object(data["network"], _NETWORK_KEYS, "network", source)
    rate = _number(net_data["rate_hz"], "network rate_hz", source)
    features = tuple(_feature(f, i, source)
                     for i, f in enumerate(_list(net_data["features"], "features", source)))
    layers = tuple(_layer(layer, i, source)
                   for i, layer in enumerate(_list(net_data["layers"], "layers", source)))
    net = Int8Net(rate, _numbers(net_data["input_scale"], "input_scale", source),
                  _numbers(net_data["output_step"], "output_step", source), features, layers)
    try:
        net.check()
    except ValueError as exc:
        raise ModelFileError(f"{source}: invalid network: {exc}") from None
    return ResidualModel(
        name=name, design_name=_name(design["name"], "design name", source, name_problem),
        design_hash=_hex32(design["hash"], "design hash", source), base=base, net=net,
        calibration_name=None if cal is None else _name(cal["name"], "calibration name",
                                                        source),
        calibration_hash=None if cal is None else _hex32(cal["hash"], "calibration hash",
                                                          source),
        training=training)


def load(path: str | Path) -> ResidualModel:
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ModelFileError(f"{path}: no such file") from None
    except OSError as exc:
        raise ModelFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        what = ("an ONNX file (a host model from `delta6 train`, or an on-chip model's float "
                "twin)" if path.suffix.lower() == ".onnx" else "not a text file")
        raise ModelFileError(f"{path}: {what}; the on-chip model is the .json that "
                             "`delta6 train --target mcu` writes") from None
    return loads(text, str(path))
