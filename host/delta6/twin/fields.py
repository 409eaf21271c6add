"""Checks of the twin's settings that name the offending field, so that a truth file read back
(``delta6 simulate --unit``) can say which of its fields is wrong, in its own terms."""
from __future__ import annotations

import math
import numbers


class FieldError(ValueError):
    """A setting is missing the mark; ``field`` names it, ``problem`` says how."""

    def __init__(self, field: str, problem: str):
        self.field = field
        self.problem = problem
        super().__init__(f"{field}: {problem}")

    def under(self, prefix: str) -> "FieldError":
        """The same problem, the field named inside a record (``measurement.`` + field)."""
        return FieldError(f"{prefix}.{self.field}", self.problem)

    def renamed(self, names: dict[str, str]) -> "FieldError":
        """The same problem, the field (or its element ``field[i]``) under another name."""
        base, bracket, rest = self.field.partition("[")
        return FieldError(names.get(base, base) + bracket + rest, self.problem)


def number(field: str, value, low: float = -math.inf, high: float = math.inf, *,
           above: bool = False, integer: bool = False, low_is: str = ""):
    """``value`` if it is a finite number in [low, high] (``above``: in (low, high]); else a
    :class:`FieldError`. A JSON ``true`` is no number, nor a float where a count is due.
    ``low_is`` names the setting ``low`` comes from, if any."""
    kinds = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kinds):
        kind = "a whole number" if integer else "a number"
        raise FieldError(field, f"takes {kind}, got {value!r}")
    if not math.isfinite(value):
        raise FieldError(field, f"must be finite, got {value}")
    if value < low or value > high or (above and value == low):
        source = f" ({low_is})" if low_is else ""
        raise FieldError(field, f"must be {_bounds(low, high, above)}{source}, got {value:g}")
    return value


def vector(field: str, value, size: int) -> tuple[float, ...]:
    """``value`` as ``size`` finite numbers (a list in a truth file)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != size:
        raise FieldError(field, f"takes {size} numbers, got {value!r}")
    return tuple(float(number(f"{field}[{i}]", v)) for i, v in enumerate(value))


def flag(field: str, value) -> bool:
    if not isinstance(value, bool):
        raise FieldError(field, f"takes true or false, got {value!r}")
    return value


def _bounds(low: float, high: float, above: bool) -> str:
    if high == math.inf:
        return f"{'>' if above else '>='} {low:g}"
    if low == -math.inf:
        return f"<= {high:g}"
    return f"within {'(' if above else '['}{low:g}, {high:g}]"
