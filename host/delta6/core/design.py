"""Design files: a Delta6 variant's parameters, loaded from TOML and validated.

A design file names every quantity with its unit in the key (``a_mm``, ``k_nm_per_rad``), so a
file can never be read in the wrong unit silently. Loading returns a :class:`Design`; anything
wrong raises :class:`DesignError` with a one-line message that names the offending field.
"""
from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.core.paths import DEFAULT_DESIGN, DESIGNS_DIR  # noqa: F401  (re-exported: the default design)

#: Longest name of a design, calibration or on-chip model: the device-info record carries each
#: in a 24-byte field, NUL-terminated.
MAX_NAME_CHARS = 23
#: The highest sample rate a Delta6 can be asked for, and an on-chip model trained at: a u16 in
#: the protocol's START and in the model header (delta6::residual::Model::rate_hz).
MAX_RATE_HZ = 0xFFFF

#: The design the tools use when none is given: the paper's Delta6.
#: Joint range of every encoder, both signs, in radians (the paper samples [-pi/6, pi/6]).
DEFAULT_JOINT_LIMIT_RAD = math.pi / 6

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
LENGTH_KEYS = ("a_mm", "b_mm", "c_mm", "la_mm", "lb_mm")
REQUIRED_KEYS = ("name",) + LENGTH_KEYS + ("theta_offset_rad", "k_nm_per_rad")
OPTIONAL_KEYS = ("joint_limit_rad", "description")

# Keys people plausibly write in another unit; mapped to the key we expect, for the message.
_UNIT_HINTS = {
    **{f"{base}_{unit}": f"{base}_mm" for base in ("a", "b", "c", "la", "lb")
       for unit in ("m", "cm", "in", "inch", "um", "")},
    **{f"{base}": f"{base}_mm" for base in ("a", "b", "c", "la", "lb")},
    "theta_offset_deg": "theta_offset_rad", "theta_offset": "theta_offset_rad",
    "k": "k_nm_per_rad", "k_nmm_per_rad": "k_nm_per_rad", "k_nm_per_deg": "k_nm_per_rad",
    "k_n_mm_per_rad": "k_nm_per_rad", "joint_limit_deg": "joint_limit_rad",
}


class DesignError(ValueError):
    """A design file or design value is unusable. ``field`` names the culprit."""

    def __init__(self, field: str, message: str, source: str | None = None):
        self.field = field
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}field '{field}': {message}")


@dataclass(frozen=True)
class Design:
    """One Delta6 variant. Lengths in mm as in the file; use :meth:`si` values for physics."""

    name: str
    a_mm: float
    b_mm: float
    c_mm: float
    la_mm: float
    lb_mm: float
    theta_offset_rad: float
    k_nm_per_rad: tuple[float, float, float, float, float, float]
    joint_limit_rad: float = DEFAULT_JOINT_LIMIT_RAD
    description: str = ""

    def joint_box(self, joints: int = 6) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper limits of the first ``joints`` joint angles, radians."""
        lim = self.joint_limit_rad
        return np.full(joints, -lim), np.full(joints, lim)

    @property
    def k(self) -> np.ndarray:
        """Per-joint spring rates, N*m/rad, shape (6,)."""
        return np.asarray(self.k_nm_per_rad, dtype=float)

    def canonical(self) -> dict:
        """The physically meaningful content, in a fixed order and form (for hashing)."""
        return {
            "a_mm": self.a_mm, "b_mm": self.b_mm, "c_mm": self.c_mm,
            "la_mm": self.la_mm, "lb_mm": self.lb_mm,
            "theta_offset_rad": self.theta_offset_rad,
            "k_nm_per_rad": list(self.k_nm_per_rad),
            "joint_limit_rad": self.joint_limit_rad,
        }

    def hash32(self) -> int:
        """32-bit identity of the physics of this design (name and description excluded).

        SHA-256 over a canonical JSON with floats written by ``repr`` (shortest round-trip
        form), truncated to 32 bits: stable across machines and Python versions.
        """
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big")

    def replace(self, **changes) -> "Design":
        """A copy with some fields changed, validated like a loaded file."""
        values = {**self.__dict__, **changes}
        values["k_nm_per_rad"] = list(values["k_nm_per_rad"])
        return validate(values, source=None)


def label_problem(name) -> str | None:
    """Why ``name`` cannot label a calibration or an on-chip model (None: it can): printable
    ASCII, not blank, at most MAX_NAME_CHARS (the device-info record carries it in 24 bytes,
    NUL-terminated). A label is no path: the generated headers escape it as a C string and
    build folders are named from a sanitized form."""
    if not isinstance(name, str) or not name.strip():
        return "must be a non-empty string"
    if len(name) > MAX_NAME_CHARS or not all(" " <= c <= "~" for c in name):
        return f"must be printable ASCII and at most {MAX_NAME_CHARS} characters"
    if name != name.strip():
        # A log's header and the device-info record would not keep the spaces at its ends.
        return f"{name!r} must be without a space at either end"
    return None


def name_problem(name) -> str | None:
    """Why ``name`` cannot name a design (None: it can): a label (:func:`label_problem`) that
    also names folders and files as is (designs/NAME.toml, build/designs/NAME/), so only
    letters, digits, '-', '_' and '.'."""
    problem = label_problem(name)
    if problem:
        return problem
    if not _NAME.fullmatch(name):
        return (f"{name!r} may hold only letters, digits, '-', '_' and '.', and starts with a "
                "letter or digit")
    return None


def _number(raw: dict, key: str, source: str | None) -> float:
    value = raw[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DesignError(key, f"must be a number, got {type(value).__name__} {value!r}", source)
    value = float(value)
    if not math.isfinite(value):
        raise DesignError(key, f"must be finite, got {value!r}", source)
    return value


#: Hard bounds: beyond them the float32 arithmetic of the board (and the reports) overflows or
#: the joint box is under a few encoder counts. Far narrower plausibility notes follow below.
MIN_LENGTH_MM, MAX_LENGTH_MM = 1e-3, 1e5
MIN_K_NM_PER_RAD, MAX_K_NM_PER_RAD = 1e-6, 1e6
MIN_JOINT_LIMIT_RAD = 0.01


def validate(raw: dict, source: str | None = None) -> Design:
    """Check a mapping of design keys and build a :class:`Design` (no geometry check)."""
    for key in raw:
        if key in REQUIRED_KEYS or key in OPTIONAL_KEYS:
            continue
        hint = _UNIT_HINTS.get(key)
        if hint:
            raise DesignError(key, f"unknown key; write '{hint}' (units are part of the key name)",
                              source)
        raise DesignError(key, "unknown key; expected one of " + ", ".join(REQUIRED_KEYS
                                                                            + OPTIONAL_KEYS), source)
    for key in REQUIRED_KEYS:
        if key not in raw:
            raise DesignError(key, "missing", source)

    name = raw["name"]
    problem = name_problem(name)
    if problem:
        raise DesignError("name", problem, source)

    lengths = {}
    for key in LENGTH_KEYS:
        value = _number(raw, key, source)
        if key == "c_mm":
            if value < 0:
                raise DesignError(key, f"must be >= 0 mm, got {value:g}", source)
        elif value <= 0:
            raise DesignError(key, f"must be > 0 mm, got {value:g}", source)
        if value > MAX_LENGTH_MM or 0 < value < MIN_LENGTH_MM:
            raise DesignError(key, f"must lie in {MIN_LENGTH_MM:g}..{MAX_LENGTH_MM:g} mm, got "
                                   f"{value:g} (the model's arithmetic is sized for that)",
                              source)
        lengths[key] = value
    if lengths["b_mm"] >= lengths["a_mm"]:
        raise DesignError("b_mm", f"must be smaller than a_mm ({lengths['a_mm']:g}), got "
                                  f"{lengths['b_mm']:g}", source)

    offset = _number(raw, "theta_offset_rad", source)
    if not -math.pi / 2 < offset < math.pi / 2:
        raise DesignError("theta_offset_rad", f"must lie in (-pi/2, pi/2) rad, got {offset:g}",
                          source)

    k_raw = raw["k_nm_per_rad"]
    if isinstance(k_raw, (list, tuple)):
        if len(k_raw) != 6:
            raise DesignError("k_nm_per_rad", f"a per-joint list needs 6 values, got {len(k_raw)}",
                              source)
        ks = []
        for i, item in enumerate(k_raw):
            ks.append(_number({f"k_nm_per_rad[{i}]": item}, f"k_nm_per_rad[{i}]", source))
    else:
        ks = [_number(raw, "k_nm_per_rad", source)] * 6
    for i, value in enumerate(ks):
        joint = f" for joint {i + 1}" if isinstance(k_raw, (list, tuple)) else ""
        if value <= 0:
            raise DesignError("k_nm_per_rad", f"must be > 0 N*m/rad, got {value:g}{joint}",
                              source)
        if not MIN_K_NM_PER_RAD <= value <= MAX_K_NM_PER_RAD:
            raise DesignError("k_nm_per_rad", f"must lie in {MIN_K_NM_PER_RAD:g}.."
                                              f"{MAX_K_NM_PER_RAD:g} N*m/rad, got {value:g}"
                                              f"{joint}", source)

    limit = DEFAULT_JOINT_LIMIT_RAD
    if "joint_limit_rad" in raw:
        limit = _number(raw, "joint_limit_rad", source)
        if not MIN_JOINT_LIMIT_RAD <= limit < math.pi / 2:
            raise DesignError("joint_limit_rad", f"must lie in [{MIN_JOINT_LIMIT_RAD:g}, pi/2) "
                                                 f"rad, got {limit:g} (the board checks the "
                                                 "box in whole encoder counts)", source)
    description = raw.get("description", "")
    if not isinstance(description, str):
        raise DesignError("description", "must be a string", source)

    return Design(name=name, theta_offset_rad=offset, k_nm_per_rad=tuple(ks),
                  joint_limit_rad=limit, description=description, **lengths)


#: Sizes a hand-sized sensor of this kind plausibly has; a value far outside reads as another
#: unit (metres or inches in a mm key, N*mm in an N*m key). The design tools take such a design
#: with a note; the firmware builds refuse it (delta6.commands.codegen.firmware_notes).
PLAUSIBLE_LENGTH_MM = (1.0, 2000.0)
PLAUSIBLE_K_NM_PER_RAD = (1e-3, 100.0)


def unit_slips(design: Design) -> list[str]:
    """One phrase per value that looks like it was written in another unit."""
    slips = []
    lo, hi = PLAUSIBLE_LENGTH_MM
    for key in LENGTH_KEYS:
        value = getattr(design, key)
        if key == "c_mm" and value == 0:
            continue
        if not lo <= value <= hi:
            guess = "metres or inches?" if value < lo else "micrometres?"
            slips.append(f"{key} = {value:g} is outside {lo:g}..{hi:g} mm ({guess})")
    lo, hi = PLAUSIBLE_K_NM_PER_RAD
    for j, value in enumerate(design.k_nm_per_rad):
        if not lo <= value <= hi:
            guess = "N*mm/rad?" if value > hi else "a tiny spring?"
            slips.append(f"k_nm_per_rad of joint {j + 1} = {value:g} is outside {lo:g}..{hi:g} "
                         f"N*m/rad ({guess})")
            break
    return slips


def unit_slip_notes(design: Design) -> list[str]:
    """:func:`unit_slips` as note lines."""
    return [f"note: design {design.name}: {slip}" for slip in unit_slips(design)]


def load(path: str | Path) -> Design:
    """Read a design file and validate its fields. Whether the kinematics is solvable over the
    whole joint box is a geometric question: :func:`delta6.core.workspace.load_checked` loads
    and answers it, for the commands that need it."""
    path = Path(path)
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8-sig")   # (an editor's BOM is not TOML)
    except FileNotFoundError:
        raise DesignError("file", "no such file", source) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DesignError("file", f"cannot be read ({exc.__class__.__name__})", source) from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DesignError("file", f"is not valid TOML ({exc})", source) from None
    return validate(raw, source)


def _shipped(matches) -> Path | None:
    """The first shipped design file (``designs/``) whose design ``matches``."""
    return next((path for path in sorted(DESIGNS_DIR.glob("*.toml")) if matches(load(path))),
                None)


def shipped_design_named(name: str) -> Path | None:
    """The shipped design file whose design is called ``name``."""
    return _shipped(lambda d: d.name == name)


def shipped_design(design_hash: int) -> Path | None:
    """The shipped design file whose physics hashes to ``design_hash``."""
    return _shipped(lambda d: d.hash32() == design_hash)
