"""Calibration files: a unit's fitted corrections to the analytical model (``docs/calibration.md``).

A calibration is what ``delta6 calibrate`` fits from one calibration run and what the
calibrated model (``delta6.core.calibrated``) applies, on the host and, compiled in by
``delta6 codegen --calibration``, on the board. The file is TOML with the unit in every key
name, like a design file. It names the design it was fitted for (name and hash), the effects it
corrects, their parameters, where and how it was fitted, and the held-out Table V before and
after. Anything wrong raises :class:`CalibrationError` with one line naming the field.

The **calibration hash** (:meth:`Calibration.hash32`) covers what changes the wrench: the
design hash and every model parameter, not the name or the fit record. The board reports it.
"""
from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from delta6.core.curves import ENCODER_HARMONICS
from delta6.core.design import MAX_NAME_CHARS, label_problem
from delta6.core.errors import UserError
from delta6.core.hashes import parse_hash32

SCHEMA = "delta6-calibration/1"
#: Effects of the twin's vocabulary a calibration corrects on the device.
CORRECTED = ("encoder_offset", "backlash", "stiffness_mismatch", "spring_hysteresis",
             "joint_friction", "geometry_error", "link_compliance", "nonlinear_spring",
             "encoder_periodic_error")
#: The rig's latency: a calibration fits it (unless the rig's is stated) and never applies it.
LATENCY = "sensor_latency"
#: Effects the fit accounts for but the device does not apply, and why.
NOT_APPLIED = {
    LATENCY: "a property of the calibration rig (the reference sensor is late), not of the "
             "unit: fitted, reported, not applied",
    "thermal_drift": "needs the unit's temperature; no gain shown with the chip's sensor: "
                     "left out",
    "harness": "a force from outside the unit (a cable to the plate) that changes with how "
               "it is routed: reported by the diagnosis, not applied",
}
#: Play radii of the hysteresis operators, encoder counts (0.006, 0.025, 0.098 rad): a file's
#: default, and the neutral calibration's.
DEFAULT_HYSTERESIS_RADII = (16, 64, 256)
#: ... and a new calibration's (0.003 to 0.2 rad, all four the board holds): a loop's shape
#: over the reversal amplitudes a run happens to make is fitted closer, so the calibration
#: carries over to runs with other amplitudes (docs/calibration.md, "Single-effect scenarios").
NEW_HYSTERESIS_RADII = (8, 32, 128, 512)
#: Speeds V of the saturated Coulomb signs clamp(v / V, -1, 1), rad/s.
DEFAULT_FRICTION_SPEEDS = (0.005, 0.02)
#: Time constant of the joint-speed filter, s.
DEFAULT_SPEED_FILTER_S = 0.02
#: The friction's speed is led by this much of its filtered acceleration, s (new calibrations;
#: a file without it has none): the filtered speed lags the true one at the reversals, where
#: the friction switches (docs/calibration.md, "A led speed").
DEFAULT_SPEED_LEAD_S = 0.01
#: Half-width of the direction-of-motion detector (backlash, pre-sliding), in half counts:
#: 3 = 1.5 counts, so +-1 count of encoder flicker does not flip it.
DEFAULT_DIRECTION_HALF_COUNTS = 3
NAME_LIMIT = MAX_NAME_CHARS


class CalibrationError(UserError):
    """A calibration file or value is unusable; the message names the field."""


def _zeros(*shape):
    return field(default_factory=lambda: np.zeros(shape))


@dataclass(frozen=True, eq=False)   # arrays inside: compare hash32() instead
class Calibration:
    """A unit's calibration. Arrays are numpy float arrays; joints 1..6, branches 1..3.

    Neutral values (zeros, ratios of one) leave the analytical model unchanged, so an effect
    not in ``effects`` simply keeps them.
    """

    name: str
    design_name: str
    design_hash: int
    effects: tuple[str, ...] = ()
    # angle side: theta = count angle - offset - e(count angle) + play / 2 * direction
    offset_rad: np.ndarray = _zeros(6)
    # e: the encoder's periodic error, per joint sin, cos of harmonics 1..4 (delta6.core.curves)
    encoder_periodic_rad: np.ndarray = _zeros(6, 2 * len(ENCODER_HARMONICS))
    backlash_play_rad: np.ndarray = _zeros(6)
    direction_half_counts: int = DEFAULT_DIRECTION_HALF_COUNTS
    # rate: spring torque = k * ratio * theta + s(count angle)
    rate_ratio: np.ndarray = field(default_factory=lambda: np.ones(6))
    # s: the spring's curve beyond its rate, per joint (|u|, u^2 coefficients; curves)
    spring_curvature: np.ndarray = _zeros(6, 2)
    # torque-side history: Prandtl-Ishlinskii plays of the count, weights per joint and radius
    hysteresis_radii_counts: tuple[int, ...] = DEFAULT_HYSTERESIS_RADII
    hysteresis_nm: np.ndarray = field(
        default_factory=lambda: np.zeros((6, len(DEFAULT_HYSTERESIS_RADII))))
    # friction from the filtered joint speed v: sum_s c_s clamp(v / V_s, -1, 1) + b v + m direction
    speed_filter_s: float = DEFAULT_SPEED_FILTER_S
    friction_speeds_rad_s: tuple[float, ...] = DEFAULT_FRICTION_SPEEDS
    friction_sign_nm: np.ndarray = field(
        default_factory=lambda: np.zeros((6, len(DEFAULT_FRICTION_SPEEDS))))
    viscous_nm_s_per_rad: np.ndarray = _zeros(6)
    presliding_nm: np.ndarray = _zeros(6)
    # the friction is known up to the speeds its run reached: beyond, held (0: no limit)
    friction_speed_limit_rad_s: np.ndarray = _zeros(6)
    # ... at the speed led by this much of its filtered acceleration, s (0: the speed itself)
    speed_lead_s: float = 0.0
    # geometry, built minus nominal, per branch; the gimbal's rotation vector
    delta_a_mm: np.ndarray = _zeros(3)
    delta_b_mm: np.ndarray = _zeros(3)
    delta_la_mm: np.ndarray = _zeros(3)
    delta_lb_mm: np.ndarray = _zeros(3)
    delta_azimuth_rad: np.ndarray = _zeros(3)
    delta_rest_angle_rad: np.ndarray = _zeros(3)
    gimbal_misalignment_rad: np.ndarray = _zeros(3)
    # load-dependent compliance: elbow turn per N*m of joint torque, platform tilt per N*m
    elbow_rad_per_nm: np.ndarray = _zeros(3)
    tilt_rad_per_nm: float = 0.0
    # where and how it was fitted (not hashed: it does not change the wrench)
    fit: dict = field(default_factory=dict, compare=False)

    # -- identity ----------------------------------------------------------------------------

    def canonical(self) -> dict:
        """What changes the wrench, in a fixed order and form (for the hash)."""
        out = {"design_hash": self.design_hash}
        for name, _ in _PARAMETERS:
            value = getattr(self, name)
            if name in _HASHED_WHEN_PRESENT and not np.any(value):
                continue        # absent curves hash as before they existed
            out[name] = np.asarray(value, dtype=float).tolist() \
                if not isinstance(value, int) else value
        return out

    def hash32(self) -> int:
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big")

    def check_design(self, design) -> None:
        """Refuse a design other than the one this calibration was fitted for."""
        if design.hash32() != self.design_hash:
            raise CalibrationError(
                f"calibration '{self.name}' was fitted for design '{self.design_name}' "
                f"(hash 0x{self.design_hash:08x}), not '{design.name}' "
                f"(hash 0x{design.hash32():08x})")

    def with_(self, **changes) -> "Calibration":
        return replace(self, **changes)

    @property
    def uses_history(self) -> bool:
        return bool(np.any(self.hysteresis_nm) or np.any(self.friction_sign_nm)
                    or np.any(self.viscous_nm_s_per_rad) or np.any(self.presliding_nm)
                    or np.any(self.backlash_play_rad))


#: Model parameters: name, shape (() scalar, "radii" / "speeds" the variable lengths).
_PARAMETERS = (
    ("offset_rad", (6,)), ("backlash_play_rad", (6,)), ("direction_half_counts", "int"),
    ("rate_ratio", (6,)),
    ("encoder_periodic_rad", (6, 2 * len(ENCODER_HARMONICS))), ("spring_curvature", (6, 2)),
    ("hysteresis_radii_counts", "radii"), ("hysteresis_nm", (6, "radii")),
    ("speed_filter_s", ()), ("friction_speeds_rad_s", "speeds"),
    ("friction_sign_nm", (6, "speeds")), ("viscous_nm_s_per_rad", (6,)),
    ("presliding_nm", (6,)), ("friction_speed_limit_rad_s", (6,)), ("speed_lead_s", ()),
    ("delta_a_mm", (3,)), ("delta_b_mm", (3,)), ("delta_la_mm", (3,)), ("delta_lb_mm", (3,)),
    ("delta_azimuth_rad", (3,)), ("delta_rest_angle_rad", (3,)),
    ("gimbal_misalignment_rad", (3,)), ("elbow_rad_per_nm", (3,)), ("tilt_rad_per_nm", ()),
)

#: Parameters added later, hashed only when not neutral: a calibration without them keeps
#: the hash it had (and the board that reports it stays recognised). The hash has no design
#: to tabulate them with, so it takes them as written; a curve whose board tables round to
#: zero is no curve for the model and the board (``curves.curve_tables``), and ``delta6
#: calibrate`` writes it as zero, so a fitted file hashes as what the board applies.
_HASHED_WHEN_PRESENT = ("encoder_periodic_rad", "spring_curvature", "friction_speed_limit_rad_s",
                        "speed_lead_s")

#: The file's sections: section -> (key in the file, attribute).
SECTIONS = {
    "angle": (("offset_rad", "offset_rad"), ("backlash_play_rad", "backlash_play_rad"),
              ("direction_half_counts", "direction_half_counts"),
              ("periodic_rad", "encoder_periodic_rad")),
    "spring": (("rate_ratio", "rate_ratio"), ("curvature", "spring_curvature")),
    "hysteresis": (("play_radii_counts", "hysteresis_radii_counts"),
                   ("weights_nm", "hysteresis_nm")),
    "friction": (("speed_filter_s", "speed_filter_s"),
                 ("sign_speeds_rad_s", "friction_speeds_rad_s"),
                 ("sign_nm", "friction_sign_nm"),
                 ("viscous_nm_s_per_rad", "viscous_nm_s_per_rad"),
                 ("presliding_nm", "presliding_nm"),
                 ("speed_limit_rad_s", "friction_speed_limit_rad_s"),
                 ("speed_lead_s", "speed_lead_s")),
    "geometry": (("delta_a_mm", "delta_a_mm"), ("delta_b_mm", "delta_b_mm"),
                 ("delta_la_mm", "delta_la_mm"), ("delta_lb_mm", "delta_lb_mm"),
                 ("delta_azimuth_rad", "delta_azimuth_rad"),
                 ("delta_rest_angle_rad", "delta_rest_angle_rad"),
                 ("gimbal_misalignment_rad", "gimbal_misalignment_rad")),
    "compliance": (("elbow_rad_per_nm", "elbow_rad_per_nm"),
                   ("tilt_rad_per_nm", "tilt_rad_per_nm")),
}
#: Plausibility bounds (|value| at most): far beyond any real unit, they catch unit slips.
_BOUNDS = {
    "offset_rad": 0.2, "backlash_play_rad": 0.2, "delta_a_mm": 5.0, "delta_b_mm": 5.0,
    "delta_la_mm": 5.0, "delta_lb_mm": 5.0, "delta_azimuth_rad": 0.1,
    "delta_rest_angle_rad": 0.1, "gimbal_misalignment_rad": 0.1, "elbow_rad_per_nm": 1.0,
    "tilt_rad_per_nm": 1.0, "hysteresis_nm": 0.5, "friction_sign_nm": 0.5,
    "viscous_nm_s_per_rad": 1.0, "presliding_nm": 0.5, "encoder_periodic_rad": 0.1,
    "spring_curvature": 2.0, "friction_speed_limit_rad_s": 100.0, "speed_lead_s": 0.1,
}


def neutral(design, name: str | None = None) -> Calibration:
    """The calibration that changes nothing (the analytical model) for ``design``."""
    return Calibration(name=name or f"{design.name}-none"[:NAME_LIMIT], design_name=design.name,
                       design_hash=design.hash32())


def new_settings(design, name: str | None = None) -> Calibration:
    """What a new calibration of ``design`` starts from: the neutral one, with the friction's
    speed led (``DEFAULT_SPEED_LEAD_S``) and four hysteresis plays (``NEW_HYSTERESIS_RADII``)."""
    return neutral(design, name).with_(
        speed_lead_s=DEFAULT_SPEED_LEAD_S, hysteresis_radii_counts=NEW_HYSTERESIS_RADII,
        hysteresis_nm=np.zeros((6, len(NEW_HYSTERESIS_RADII))))


# -- validation ------------------------------------------------------------------------------

def _fail(source, key, message):
    where = f"{source}: " if source else ""
    raise CalibrationError(f"{where}field '{key}': {message}")


def _array(value, shape, key, source) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        ragged = isinstance(value, list) and any(isinstance(v, list) for v in value)
        _fail(source, key, "must be a table of numbers, its rows of one length" if ragged
              else f"must be numbers, got {value!r}"[:120])
    if any(isinstance(v, bool) for v in np.ravel(np.asarray(value, dtype=object))):
        _fail(source, key, "must be numbers, got a boolean")
    if arr.shape != shape:
        _fail(source, key, f"needs shape {list(shape)}, got {list(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        _fail(source, key, "must be finite")
    return arr


def validate(cal: Calibration, source: str | None = None) -> Calibration:
    """Check every field of ``cal``; returns it with arrays normalised."""
    problem = label_problem(cal.name)
    if problem:     # a label: the board reports it, the calibration header holds it escaped
        _fail(source, "name", problem)
    if not isinstance(cal.design_hash, int) or not 0 <= cal.design_hash < 2**32:
        _fail(source, "design.hash", "must be a 32-bit hash like 0x535534af")
    for effect in cal.effects:
        if effect not in CORRECTED:
            _fail(source, "effects", f"unknown or uncorrectable effect {effect!r} (one of "
                                     f"{', '.join(CORRECTED)})")
    radii = cal.hysteresis_radii_counts
    if not (isinstance(radii, tuple) and 1 <= len(radii) <= 4
            and all(isinstance(r, int) and not isinstance(r, bool) and 1 <= r <= 4096
                    for r in radii) and len(set(radii)) == len(radii)):
        _fail(source, "hysteresis.play_radii_counts", "must be 1..4 distinct whole counts in "
                                                      "1..4096")
    speeds = cal.friction_speeds_rad_s
    if not (isinstance(speeds, tuple) and 1 <= len(speeds) <= 4
            and all(isinstance(s, float) and math.isfinite(s) and 1e-4 <= s <= 10 for s in speeds)):
        _fail(source, "friction.sign_speeds_rad_s", "must be 1..4 speeds in 1e-4..10 rad/s")
    half = cal.direction_half_counts
    if not (isinstance(half, int) and not isinstance(half, bool) and 1 <= half <= 64):
        _fail(source, "angle.direction_half_counts", "must be a whole number in 1..64")
    if not (isinstance(cal.speed_filter_s, float) and 1e-4 <= cal.speed_filter_s <= 10):
        _fail(source, "friction.speed_filter_s", "must lie in 1e-4..10 s")
    changes = {}
    for name_, shape in _PARAMETERS:
        if shape in ("int", "radii", "speeds") or name_ == "speed_filter_s":
            continue
        dims = tuple(len(radii) if d == "radii" else len(speeds) if d == "speeds" else d
                     for d in shape)
        value = _array(getattr(cal, name_), dims, _key_of(name_), source)
        bound = _BOUNDS.get(name_)
        if bound is not None and np.any(np.abs(value) > bound):
            _fail(source, _key_of(name_), f"|value| must be at most {bound:g}: wrong unit?")
        changes[name_] = value if dims else float(value)
    if np.any(changes["friction_speed_limit_rad_s"] < 0):
        _fail(source, "friction.speed_limit_rad_s", "must be >= 0 rad/s (0: no limit)")
    if changes["speed_lead_s"] < 0:
        _fail(source, "friction.speed_lead_s", "must be >= 0 s (0: no lead)")
    ratio = changes["rate_ratio"]
    if np.any(ratio < 0.5) or np.any(ratio > 2.0):
        _fail(source, "spring.rate_ratio", "must lie in 0.5..2 (true / nominal spring rate)")
    return replace(cal, **changes)


def _key_of(attribute: str) -> str:
    for section, pairs in SECTIONS.items():
        for key, attr in pairs:
            if attr == attribute:
                return f"{section}.{key}"
    return attribute


# -- the file --------------------------------------------------------------------------------

def _toml_value(value) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            raise CalibrationError(f"cannot write a non-finite number ({v})")
        return repr(v)
    if isinstance(value, np.ndarray):
        return _toml_value(value.tolist())
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise CalibrationError(f"cannot write {type(value).__name__} to TOML")


def _table_lines(prefix: str, table: dict) -> list[str]:
    scalars = [(k, v) for k, v in table.items() if not isinstance(v, dict)]
    nested = [(k, v) for k, v in table.items() if isinstance(v, dict)]
    lines = [f"[{prefix}]"] + [f"{k} = {_toml_value(v)}" for k, v in scalars]
    for k, v in nested:
        lines += [""] + _table_lines(f"{prefix}.{k}", v)
    return lines


def dumps(cal: Calibration) -> str:
    """The TOML text of a calibration (floats written to round-trip exactly)."""
    cal = validate(cal)
    lines = [
        "# Delta6 calibration: corrections to the analytical model for one unit.",
        "# Written by `delta6 calibrate`; docs/calibration.md explains every field.",
        f"schema = {_toml_value(SCHEMA)}",
        f"name = {_toml_value(cal.name)}",
        f"hash = \"0x{cal.hash32():08x}\"  # of the design hash and the model parameters",
        f"effects = {_toml_value(list(cal.effects))}",
        "",
        "[design]",
        f"name = {_toml_value(cal.design_name)}",
        f"hash = \"0x{cal.design_hash:08x}\"",
    ]
    for section, pairs in SECTIONS.items():
        lines += ["", f"[{section}]"]
        for key, attr in pairs:
            lines.append(f"{key} = {_toml_value(getattr(cal, attr))}")
    if cal.fit:
        lines += [""] + _table_lines("fit", cal.fit)
    return "\n".join(lines) + "\n"


def save(cal: Calibration, path: str | Path) -> Path:
    """Write atomically (temporary file, then rename)."""
    path = Path(path)
    text = dumps(cal)
    tmp = path.with_name(path.name + ".partial")
    try:
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    except OSError as exc:
        raise CalibrationError(f"cannot write {path}: {exc.strerror}") from None
    return path


def _hash(value, key, source) -> int:
    try:
        return parse_hash32(value)
    except ValueError as exc:
        _fail(source, key, str(exc))


def loads(text: str, source: str | None = None) -> Calibration:
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CalibrationError(f"{source or 'calibration'}: not valid TOML ({exc})") from None
    if raw.get("schema") != SCHEMA:
        _fail(source, "schema", f"must be {SCHEMA!r} (is this a calibration file?)")
    known = {"schema", "name", "hash", "effects", "design", "fit", *SECTIONS}
    for key in raw:
        if key not in known:
            _fail(source, key, "unknown key; expected one of " + ", ".join(sorted(known)))
    for key in ("name", "design"):
        if key not in raw:
            _fail(source, key, "missing")
    design = raw["design"]
    if not isinstance(design, dict) or set(design) != {"name", "hash"}:
        _fail(source, "design", "must hold exactly 'name' and 'hash'")
    values = {}
    for section, pairs in SECTIONS.items():
        table = raw.get(section, {})
        if not isinstance(table, dict):
            _fail(source, section, "must be a table")
        allowed = {k for k, _ in pairs}
        for key in table:
            if key not in allowed:
                _fail(source, f"{section}.{key}", "unknown key; expected one of "
                      + ", ".join(sorted(allowed)))
        for key, attr in pairs:
            if key not in table:
                continue
            value = table[key]
            if attr == "hysteresis_radii_counts":
                value = tuple(value) if isinstance(value, list) else value
            elif attr == "friction_speeds_rad_s":
                value = tuple(float(v) if isinstance(v, (int, float)) and not isinstance(v, bool)
                              else v for v in value) if isinstance(value, list) else value
            elif attr in ("speed_filter_s", "tilt_rad_per_nm", "speed_lead_s"):
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    _fail(source, f"{section}.{key}", "must be a number")
                value = float(value)
            values[attr] = value
    # Variable-length tables default to zeros of the file's lengths.
    radii = values.get("hysteresis_radii_counts", DEFAULT_HYSTERESIS_RADII)
    speeds = values.get("friction_speeds_rad_s", DEFAULT_FRICTION_SPEEDS)
    values.setdefault("hysteresis_nm", np.zeros((6, len(radii)) if isinstance(radii, tuple)
                                                else (6, 0)))
    values.setdefault("friction_sign_nm", np.zeros((6, len(speeds)) if isinstance(speeds, tuple)
                                                   else (6, 0)))
    effects = raw.get("effects", [])
    if not isinstance(effects, list) or not all(isinstance(e, str) for e in effects):
        _fail(source, "effects", "must be a list of effect names")
    fit = raw.get("fit", {})
    if not isinstance(fit, dict):
        _fail(source, "fit", "must be a table")
    cal = Calibration(name=raw["name"], design_name=str(design["name"]),
                      design_hash=_hash(design["hash"], "design.hash", source),
                      effects=tuple(effects), fit=fit, **values)
    cal = validate(cal, source)
    if "hash" in raw and _hash(raw["hash"], "hash", source) != cal.hash32():
        _fail(source, "hash", f"is {raw['hash']} but the parameters hash to "
                              f"0x{cal.hash32():08x}: the file was edited; rerun "
                              "delta6 calibrate, or delete the hash line to accept the edit")
    return cal


def load(path: str | Path) -> Calibration:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")   # (an editor's BOM is not TOML)
    except FileNotFoundError:
        raise CalibrationError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{path}: cannot be read ({exc.__class__.__name__})") from None
    return loads(text, str(path))


__all__ = ["Calibration", "CalibrationError", "CORRECTED", "LATENCY", "NOT_APPLIED", "SCHEMA",
           "dumps", "loads", "load", "save", "neutral", "validate"]


def check_log_meta(meta: dict, design, calibration: Calibration | None = None,
                   source: str = "the log") -> None:
    """Refuse to mix a log with another design or calibration than the one it names in its
    header (``design_hash``, ``calibration_hash``: written by the logger from the device
    info; without the hash, the ``design`` name). A log that names none is taken as it is."""
    named = meta.get("design_hash")
    if named is not None:
        try:
            value = int(str(named), 16)
        except ValueError:
            value = None
        if value is not None and value != design.hash32():
            raise CalibrationError(f"{source} was recorded with design {meta.get('design', '?')}"
                                   f" ({named}), not '{design.name}' (0x{design.hash32():08x}): "
                                   "pass that design's file with --design")
    elif meta.get("design") not in (None, "", design.name):
        # A header that names its design without the hash (a rig's, a simulator's) is held to
        # the name: another design's geometry would fit the log's error away.
        raise CalibrationError(f"{source} names design '{meta['design']}' in its header, not "
                               f"'{design.name}': pass that design with --design")
    named = meta.get("calibration_hash")
    if named is not None and calibration is not None:
        try:
            value = int(str(named), 16)
        except ValueError:
            value = None
        if value is not None and value != calibration.hash32():
            raise CalibrationError(
                f"{source} was recorded by a board with calibration "
                f"{meta.get('calibration', '?')} ({named}), not '{calibration.name}' "
                f"(0x{calibration.hash32():08x})")
