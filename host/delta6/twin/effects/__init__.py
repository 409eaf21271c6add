"""The effect vocabulary of the digital twin (shared with the gap diagnosis): one module per
effect, and the registry by name."""
from __future__ import annotations

from delta6.twin.effects.backlash import Backlash
from delta6.twin.effects.base import Effect, EffectError, ParamSpec, Signals, Stage
from delta6.twin.effects.encoder_offset import EncoderOffset
from delta6.twin.effects.encoder_periodic_error import EncoderPeriodicError
from delta6.twin.effects.geometry_error import GeometryError
from delta6.twin.effects.harness import Harness
from delta6.twin.effects.joint_friction import JointFriction
from delta6.twin.effects.link_compliance import LinkCompliance
from delta6.twin.effects.nonlinear_spring import NonlinearSpring
from delta6.twin.effects.sensor_latency import SensorLatency
from delta6.twin.effects.spring_hysteresis import SpringHysteresis
from delta6.twin.effects.stiffness_mismatch import StiffnessMismatch
from delta6.twin.effects.thermal_drift import ThermalDrift

#: name -> effect class, in the order of the effect vocabulary (docs/twin.md); the diagnosis
#: names its terms alike (tests/evaluation/test_effect_names.py).
REGISTRY: dict[str, type[Effect]] = {cls.NAME: cls for cls in (
    EncoderOffset, StiffnessMismatch, GeometryError, SpringHysteresis, JointFriction, Backlash,
    LinkCompliance, SensorLatency, ThermalDrift,
    # Beyond the first vocabulary: effects real magnetic-encoder sensors show.
    NonlinearSpring, EncoderPeriodicError, Harness)}
EFFECT_NAMES = tuple(REGISTRY)


def effect_class(name: str) -> type[Effect]:
    try:
        return REGISTRY[name]
    except KeyError:
        raise EffectError(f"unknown effect {name!r} (one of {', '.join(EFFECT_NAMES)})") from None


def registry_info() -> dict:
    """The vocabulary as plain data (JSON-able): per effect, where it acts, its formulations,
    and per parameter its unit, shape, realistic range, sign and which formulations use it."""
    return {name: {
        "acts_on": [s.value for s in cls.ACTS_ON],
        "formulations": list(cls.FORMULATIONS),
        "per_joint": cls.PER_JOINT,
        "parameters": {s.name: {"unit": s.unit, "shape": s.shape, "realistic": [s.low, s.high],
                                "sign": s.sign, "primary": s.primary, "valid": list(s.valid),
                                "formulations": list(s.formulations or cls.FORMULATIONS),
                                "doc": s.doc} for s in cls.SPECS},
        "doc": " ".join((cls.__doc__ or "").split()),
    } for name, cls in REGISTRY.items()}


__all__ = ["registry_info", "Effect", "EffectError", "ParamSpec", "Signals", "Stage", "REGISTRY", "EFFECT_NAMES",
           "effect_class"]
