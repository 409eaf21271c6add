"""What every unmodelled effect of the twin has in common: where it acts, its parameters
(physical units, realistic ranges), how they are drawn for a magnitude, and its truth record.

An effect acts at exactly the stages it declares in ``acts_on``; the plant (``twin.plant``)
calls only the hooks of those stages, in a fixed order:

* ``TORQUE``: the joint torques, spring side (``spring_scale`` multiplies the spring rate,
  ``extra_torque`` adds to the spring torque);
* ``GEOMETRY``: the mechanism that turns joint torques into a wrench (``geometry``);
* ``TIME``: when the reference sensor sees the wrench (``reference``);
* ``ANGLE``: what the encoders read of the joint angles (``encoder``).
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from delta6.core.errors import UserError
from delta6.core.operators import first_order

JOINTS = 6
BRANCHES = 3


class Stage(enum.Enum):
    TORQUE = "torque"
    GEOMETRY = "geometry"
    TIME = "time"
    ANGLE = "angle"


class EffectError(UserError):
    """An effect request (name, formulation, parameter, value) is not valid."""


@dataclass
class Signals:
    """What the plant's effects see, on the simulation's fine time grid (M samples)."""

    t: np.ndarray         # (M,) s
    q: np.ndarray         # (M, 6) true joint deflections, link side, rad
    qd: np.ndarray        # (M, 6) their rates, rad/s
    temp_c: np.ndarray    # (M,) ambient temperature, degC
    nominal: object       # model.Params of the design (the analytical model's parameters)
    _lagged_temp: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def dt(self) -> float:
        return grid_step(self.t)

    def rows(self, index) -> "Signals":
        """The signals at some of the samples (for the history-free stages)."""
        return Signals(self.t[index], self.q[index], self.qd[index], self.temp_c[index],
                       self.nominal)

    def lagged_temp(self, lag_s: float) -> np.ndarray:
        """``temp_c`` through a first-order lag of time constant ``lag_s`` (backward Euler,
        started settled), computed once per lag: a thermal effect acts on two stages."""
        if lag_s not in self._lagged_temp:
            self._lagged_temp[lag_s] = first_order(self.temp_c, lag_s / (lag_s + self.dt))
        return self._lagged_temp[lag_s]


def grid_step(t: np.ndarray) -> float:
    """The step of a uniform time grid (0 with fewer than two samples)."""
    return float(t[1] - t[0]) if len(t) > 1 else 0.0


_SHAPES = {"joint": (JOINTS,), "branch": (BRANCHES,), "vec3": (3,), "scalar": ()}


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an effect.

    ``low``..``high`` is the documented realistic range of its magnitude. A *primary* parameter
    is the strength of the effect and follows the requested magnitude m in [0, 1] (log-scale:
    m = 0 is ``low``, m = 1 is ``high``), with a +-25 % spread between joints; a *shape*
    parameter (``primary=False``) is drawn anywhere in its range whatever the magnitude.
    ``sign``: '+' positive, '-' negative, '+-' random sign per element.
    ``valid`` bounds what the simulator accepts at all (explicit values may leave the
    realistic range, never the valid one).
    """

    name: str
    unit: str
    shape: str
    low: float
    high: float
    doc: str
    sign: str = "+"
    primary: bool = True
    neutral: float = 0.0
    valid: tuple[float, float] = (0.0, math.inf)
    formulations: tuple[str, ...] | None = None   # None: every formulation uses it

    @property
    def dims(self) -> tuple[int, ...]:
        return _SHAPES[self.shape]

    def used_by(self, formulation: str) -> bool:
        return self.formulations is None or formulation in self.formulations

    def draw(self, rng: np.random.Generator, magnitude: float) -> np.ndarray:
        size = self.dims
        if self.primary:
            level = self.low * (self.high / self.low) ** magnitude
            values = np.clip(level * np.exp(rng.uniform(-0.25, 0.25, size)), self.low, self.high)
        else:
            values = np.exp(rng.uniform(math.log(self.low), math.log(self.high), size))
        if self.sign == "-":
            values = -values
        elif self.sign == "+-":
            values = values * rng.choice([-1.0, 1.0], size)
        return np.asarray(values, dtype=float)

    def coerce(self, effect: str, raw) -> np.ndarray:
        """An explicit value: a number (broadcast) or one per element; validated."""
        values = np.asarray(raw, dtype=float)
        if values.ndim == 0:
            values = np.full(self.dims, float(values))
        if values.shape != self.dims:
            want = self.dims[0] if self.dims else 1
            raise EffectError(f"{effect}: {self.name} takes one number or {want} values, "
                              f"got {values.size}")
        if not np.all(np.isfinite(values)):
            raise EffectError(f"{effect}: {self.name} must be finite, got {_fmt(values)}")
        lo, hi = self.valid
        if np.any(values < lo) or np.any(values > hi):
            raise EffectError(f"{effect}: {self.name} must lie in [{lo:g}, {hi:g}] {self.unit}, "
                              f"got {_fmt(values)}")
        return values


def _fmt(values: np.ndarray) -> str:
    return "/".join(f"{v:g}" for v in np.ravel(values))


@dataclass
class Effect:
    """Base class: a configured effect (formulation + parameter values)."""

    NAME: ClassVar[str] = ""
    ACTS_ON: ClassVar[tuple[Stage, ...]] = ()
    FORMULATIONS: ClassVar[tuple[str, ...]] = ()
    SPECS: ClassVar[tuple[ParamSpec, ...]] = ()
    PER_JOINT: ClassVar[bool] = True    # accepts ``joints=`` (restrict to some joints)
    ORDER: ClassVar[int] = 0            # order inside a stage (mechanical before readout)

    formulation: str
    params: dict[str, np.ndarray]
    magnitude: float | None = None
    joints: tuple[int, ...] = tuple(range(1, JOINTS + 1))

    # -- construction ---------------------------------------------------------------------

    @classmethod
    def specs_for(cls, formulation: str) -> tuple[ParamSpec, ...]:
        return tuple(s for s in cls.SPECS if s.used_by(formulation))

    @classmethod
    def build(cls, rng: np.random.Generator, *, formulation: str | None = None,
              magnitude: float | None = None, joints=None, overrides: dict | None = None,
              ) -> "Effect":
        """Draw the parameters not given in ``overrides`` for ``magnitude`` (default 0.5)."""
        formulation = cls._formulation(formulation or cls.FORMULATIONS[0])
        m = cls._magnitude(0.5 if magnitude is None else magnitude)
        joints = cls._joints(joints)
        overrides = dict(overrides or {})
        specs = cls._specs(formulation, overrides)
        params = {}
        # Every spec is drawn (in a fixed order) even when overridden, so that one override
        # does not change the draws of the others.
        for name, spec in specs.items():
            drawn = spec.draw(rng, m)
            value = spec.coerce(cls.NAME, overrides[name]) if name in overrides else drawn
            if spec.shape == "joint" and spec.primary:   # the strength: zero elsewhere
                mask = np.isin(np.arange(1, JOINTS + 1), joints)
                value = np.where(mask, value, spec.neutral)
            params[name] = value
        # The magnitude the draws used; none when every strength parameter was given.
        drawn_with = None if all(s.name in overrides for s in specs.values() if s.primary) else m
        return cls(formulation=formulation, params=params, magnitude=drawn_with, joints=joints)

    @classmethod
    def _formulation(cls, formulation) -> str:
        if formulation not in cls.FORMULATIONS:
            raise EffectError(f"{cls.NAME}: unknown formulation {formulation!r} (one of "
                              f"{', '.join(cls.FORMULATIONS)})")
        return formulation

    @classmethod
    def _magnitude(cls, magnitude) -> float:
        try:
            m = float(magnitude)
        except (TypeError, ValueError):
            raise EffectError(f"{cls.NAME}: magnitude takes a number, got {magnitude!r}") from None
        if not 0.0 <= m <= 1.0:   # NaN fails too
            raise EffectError(f"{cls.NAME}: magnitude must lie in [0, 1], got {m:g}")
        return m

    @classmethod
    def _specs(cls, formulation: str, given) -> dict[str, ParamSpec]:
        """The formulation's parameters by name; a name in ``given`` that it lacks is refused."""
        specs = {s.name: s for s in cls.specs_for(formulation)}
        unknown = set(given) - set(specs)
        if unknown:
            known = ", ".join(specs)
            raise EffectError(f"{cls.NAME}: unknown parameter {sorted(unknown)[0]!r} for "
                              f"formulation {formulation} (one of {known})")
        return specs

    @classmethod
    def _joints(cls, joints) -> tuple[int, ...]:
        if joints is None:
            return tuple(range(1, JOINTS + 1))
        if not cls.PER_JOINT:
            raise EffectError(f"{cls.NAME} acts on the whole mechanism; it takes no joints=")
        wrong = EffectError(f"{cls.NAME}: joints must be numbers 1..6, got {joints!r}")
        try:
            given = [float(j) for j in np.atleast_1d(joints)]
        except (TypeError, ValueError):
            raise wrong from None
        # A whole number each (no 1.5 rounded down, no NaN or infinity).
        if not given or not all(j.is_integer() and 1 <= j <= JOINTS for j in given):
            raise wrong
        return tuple(sorted({int(j) for j in given}))

    # -- hooks, by stage (the plant calls only those of the stages in ACTS_ON); the defaults
    # -- change nothing, so a TORQUE effect implements one or both of its two hooks.

    def spring_scale(self, sig: Signals):
        """TORQUE: factor on the spring rate, (6,) or (M, 6)."""
        return 1.0

    def extra_torque(self, sig: Signals):
        """TORQUE: torque added to the spring torque, (M, 6), N*m."""
        return 0.0

    def geometry(self, geo, sig: Signals, torque: np.ndarray):
        """GEOMETRY: the built mechanism (``statics.PlantGeometry``) under the joint torques."""
        return geo

    def reference(self, wrench: np.ndarray, sig: Signals) -> np.ndarray:
        """TIME: the wrench as the reference sensor reports it, on the fine grid."""
        return wrench

    def encoder(self, angle: np.ndarray, sig: Signals) -> np.ndarray:
        """ANGLE: what the encoders read, (M, 6) rad."""
        return angle

    # -- truth -----------------------------------------------------------------------------

    def summary(self) -> dict:
        """Formulation-independent quantities in physical units (subclasses)."""
        return {}

    def p(self, name: str) -> np.ndarray:
        return self.params[name]

    def to_truth(self) -> dict:
        units = {s.name: s.unit for s in self.specs_for(self.formulation)}
        return {
            "name": self.NAME,
            "formulation": self.formulation,
            "acts_on": [s.value for s in self.ACTS_ON],
            "magnitude": self.magnitude,
            "joints": list(self.joints),
            "parameters": {k: _jsonable(v) for k, v in self.params.items()},
            "units": units,
            "summary": {k: _jsonable(v) for k, v in self.summary().items()},
        }

    @classmethod
    def from_truth(cls, record: dict) -> "Effect":
        """Rebuild exactly the effect a truth record describes (no drawing), checked as
        :meth:`build` checks a request: a hand-edited value is refused, naming its parameter."""
        formulation = cls._formulation(record["formulation"])
        given = record["parameters"]
        if not isinstance(given, dict):
            raise EffectError(f"{cls.NAME}: parameters takes a mapping, got {given!r}")
        specs = cls._specs(formulation, given)
        params = {}
        for name, spec in specs.items():
            if name not in given:
                raise EffectError(f"{cls.NAME}: truth record lacks parameter {name!r}")
            try:
                params[name] = spec.coerce(cls.NAME, given[name])
            except (TypeError, ValueError):   # not numbers at all (a string, a nested list)
                raise EffectError(f"{cls.NAME}: {name} takes numbers, got "
                                  f"{given[name]!r}") from None
        magnitude = record.get("magnitude")
        # An effect of the whole mechanism records every joint; build() takes none for it.
        joints = record.get("joints")
        if not cls.PER_JOINT and joints == list(range(1, JOINTS + 1)):
            joints = None
        return cls(formulation=formulation, params=params,
                   magnitude=None if magnitude is None else cls._magnitude(magnitude),
                   joints=cls._joints(joints))


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value
