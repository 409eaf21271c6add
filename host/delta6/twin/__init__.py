"""The digital twin: a Delta6 plant simulator with the effects the analytical model leaves out
(docs/twin.md).

    from delta6.twin import simulate, scenario_effects, make_effect
    result = simulate(design, scenario_effects("paper", seed=1), duration_s=600, seed=1)
    result.theta, result.wrench, result.truth, result.gap()
"""
from __future__ import annotations

from delta6.twin.effects import (
                      EFFECT_NAMES,
                      REGISTRY,
                      Effect,
                      EffectError,
                      ParamSpec,
                      Stage,
                      effect_class,
                      registry_info,
)
from delta6.twin.measurement import Measurement
from delta6.twin.realtime import EncoderSample, EncoderTrack, iter_realtime, to_counts, write_log
from delta6.twin.scenarios import (
                      SCENARIOS,
                      EffectRequest,
                      build_effects,
                      make_effect,
                      parse_request,
                      random_effect,
                      random_effects,
                      scenario_effects,
)
from delta6.twin.simulator import SimResult, simulate
from delta6.twin.temperature import TemperatureSettings
from delta6.twin.trajectory import FunctionPath, RandomTrajectory, TrajectorySettings
from delta6.twin.truth import (
                      effects_from_truth,
                      read_truth,
                      replay_arguments,
                      same_unit,
                      truth_path,
                      without,
                      write_truth,
)

__all__ = [
    "EFFECT_NAMES", "REGISTRY", "Effect", "EffectError", "ParamSpec", "Stage", "effect_class",
    "Measurement", "EncoderSample", "EncoderTrack", "iter_realtime", "to_counts", "write_log", "SCENARIOS",
    "EffectRequest", "build_effects", "make_effect", "parse_request", "random_effect",
    "random_effects", "scenario_effects", "SimResult", "simulate", "TemperatureSettings",
    "FunctionPath", "RandomTrajectory", "TrajectorySettings", "effects_from_truth",
    "read_truth", "replay_arguments", "same_unit", "truth_path", "write_truth", "without", "registry_info",
]
