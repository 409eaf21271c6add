"""Named scenarios, effect requests (``name:key=value,...`` on the command line) and random
draws of effects for blind benchmarks.

An effect's parameters come from its own random stream (seed, effect name): the same seed and
request give the same parameters whatever else is active.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from delta6.twin.effects import EFFECT_NAMES, Effect, EffectError, effect_class
from delta6.twin.streams import stream

#: Magnitude of an effect requested without one (the middle of its realistic range, log scale).
DEFAULT_MAGNITUDE = 0.5


@dataclass(frozen=True)
class EffectRequest:
    """What a user asks for; ``params`` override drawn values (numbers or per-element lists)."""

    name: str
    formulation: str | None = None
    magnitude: float | None = None
    joints: tuple[int, ...] | None = None
    params: dict = field(default_factory=dict)


def make_effect(name: str, seed: int, *, formulation: str | None = None,
                magnitude: float | None = None, joints=None, **params) -> Effect:
    """A configured effect; parameters not given are drawn for ``magnitude`` from the seed."""
    cls = effect_class(name)
    m = DEFAULT_MAGNITUDE if magnitude is None else magnitude
    return cls.build(stream(seed, "effect " + name), formulation=formulation, magnitude=m,
                     joints=joints, overrides=params)


def refuse_repeats(requests) -> None:
    """A run takes each effect once."""
    seen = set()
    for r in requests:
        if r.name in seen:
            raise EffectError(f"effect {r.name} requested twice")
        seen.add(r.name)


def build_effects(requests, seed: int, magnitude: float | None = None) -> list[Effect]:
    """Effects for a list of requests; ``magnitude`` applies where a request has none."""
    refuse_repeats(requests)
    return [make_effect(r.name, seed, formulation=r.formulation,
                        magnitude=r.magnitude if r.magnitude is not None else magnitude,
                        joints=r.joints, **r.params) for r in requests]


def random_effect(name: str, seed: int, *, magnitude_range=(0.0, 1.0)) -> Effect:
    """An effect with a formulation and magnitude drawn from the seed (blind benchmarks:
    fresh seeds give unseen formulations, magnitudes and per-joint values)."""
    rng = stream(seed, "draw " + name)
    cls = effect_class(name)
    formulation = str(rng.choice(cls.FORMULATIONS))
    magnitude = float(rng.uniform(*magnitude_range))
    return make_effect(name, seed, formulation=formulation, magnitude=magnitude)


def random_effects(names, seed: int, *, magnitude_range=(0.0, 1.0)) -> list[Effect]:
    return [random_effect(n, seed, magnitude_range=magnitude_range) for n in names]


# --- parsing ``name[:key=value,...]`` ---------------------------------------------------------

def parse_request(text: str) -> EffectRequest:
    """``backlash``, ``joint_friction:coulomb_nm=0.01,formulation=lugre``,
    ``stiffness_mismatch:deviation=0.05/0/0/0/0/0``, ``backlash:joints=4/5,magnitude=0.3``."""
    name, _, rest = text.strip().partition(":")
    name = name.strip()
    effect_class(name)   # names the valid effects if unknown
    formulation, magnitude, joints, params = None, None, None, {}
    for item in filter(None, (part.strip() for part in rest.split(","))):
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key or not value:
            raise EffectError(f"{name}: expected key=value, got {item!r}")
        if key == "formulation":
            formulation = value
        elif key == "magnitude":
            magnitude = _number(name, key, value)
        elif key == "joints":
            joints = tuple(_joint(name, v) for v in value.split("/"))
        else:
            numbers = [_number(name, key, v) for v in value.split("/")]
            params[key] = numbers[0] if len(numbers) == 1 else numbers
    return EffectRequest(name, formulation, magnitude, joints, params)


def _number(effect: str, key: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise EffectError(f"{effect}: {key} takes numbers, got {text!r}") from None
    if not np.isfinite(value):
        raise EffectError(f"{effect}: {key} must be finite, got {text!r}")
    return value


def _joint(effect: str, text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise EffectError(f"{effect}: joints takes joint numbers 1..6 separated by '/', "
                          f"got {text!r}") from None


# --- named scenarios ----------------------------------------------------------------------------

#: The `paper` scenario: explicit parameters (not drawn), calibrated so that the analytical
#: model's error reproduces the paper's Table V analytical row (docs/twin.md explains how).
PAPER = (
    EffectRequest("stiffness_mismatch", params={
        "deviation": [0.0548, -0.0131, 0.0877, 0.0732, -0.0672, 0.005]}),
    EffectRequest("encoder_offset", params={
        "offset_rad": [0.002, -0.0015, 0.0025, -0.002, 0.0015, -0.001]}),
    EffectRequest("geometry_error", params={
        "delta_a_mm": [0.2, -0.15, 0.1], "delta_b_mm": [-0.1, 0.15, 0.05],
        "delta_la_mm": [0.15, -0.1, 0.2], "delta_lb_mm": [0.5, -0.4, 0.3],
        "delta_azimuth_rad": [0.004, -0.003, 0.002], "delta_rest_angle_rad": [0.005, -0.004, 0.003],
        "gimbal_misalignment_rad": [0.006, -0.005, 0.004]}),
    EffectRequest("spring_hysteresis", formulation="bouc_wen", params={
        "half_width_nm": 0.003, "reversal_angle_rad": 0.03}),
    EffectRequest("joint_friction", formulation="coulomb_viscous", params={
        "coulomb_nm": 0.002, "viscous_nm_s_per_rad": 0.002, "smoothing_rad_s": 0.005}),
    EffectRequest("backlash", formulation="dead_zone", params={"play_rad": 0.008}),
    EffectRequest("link_compliance", formulation="linear", params={
        "elbow_mm_per_n": 0.15, "rod_mm_per_n": 0.02, "tilt_rad_per_nm": 0.08}),
    EffectRequest("sensor_latency", formulation="delay", params={"latency_s": 0.01}),
)

SCENARIOS: dict[str, tuple[EffectRequest, ...]] = {
    "ideal": (),
    "paper": PAPER,
    **{name: (EffectRequest(name),) for name in EFFECT_NAMES},
}

SCENARIO_HELP = {
    "ideal": "no effects: the analytical model's error is the noise and quantization floor",
    "paper": "the combination that reproduces the paper's Table V analytical row",
    **{name: f"{name} alone at a mid-range realistic magnitude" for name in EFFECT_NAMES},
}


def scenario_effects(name: str, seed: int = 0, magnitude: float | None = None) -> list[Effect]:
    try:
        requests = SCENARIOS[name]
    except KeyError:
        raise EffectError(f"unknown scenario {name!r} (one of {', '.join(SCENARIOS)})") from None
    return build_effects(requests, seed, magnitude)
