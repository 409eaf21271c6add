"""What the friction's led speed buys on the chip: the figures behind docs/calibration.md's
"Limits of a causal correction", "A led speed".

    .venv/bin/python tools/study_speed_lead.py                     # ~15 min
    .venv/bin/python tools/study_speed_lead.py --leads 0,0.02 --seeds 4 --no-paper

The board's joint speed is a filtered count difference (``core.calibrated.filtered_speed``):
it lags the true speed, and a friction that switches with the sign of the true speed is
switched late. The calibrated model leads the friction's speed by ``speed_lead_s`` of its
filtered acceleration (``core.calibrated.led_speed``; 10 ms in a new calibration). This study
calibrates each unit with other leads (the calibration's setting, and the diagnosis's causal
view with it, so the on-chip prediction follows) on 2000 s (seed s) and scores it on 600 s of
the same unit (seed s + 1): the calibrated p99 against the diagnosis's on-chip prediction.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

import delta6.diagnosis.data as data_mod
from delta6 import twin
from delta6.calibration import calibrate
from delta6.core import accuracy
from delta6.core.calibrated import CalibratedModel
from delta6.core.calibration import new_settings
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.spec import full_scale
from delta6.core.workspace import load_checked


def case(design, scenario: str, seed: int, lead: float) -> tuple[np.ndarray, np.ndarray]:
    """(on-chip prediction, calibrated p99 on the unseen run), % FS per axis."""
    # The diagnosis predicts for the lead a new calibration takes: this study's.
    data_mod.DEFAULT_SPEED_LEAD_S = lead
    effects = twin.scenario_effects(scenario, seed=seed)
    run = twin.simulate(design, effects, duration_s=2000, rate_hz=50, seed=seed,
                        scenario=scenario)
    fit = calibrate(run, design, settings=new_settings(design).with_(speed_lead_s=lead))
    check = twin.simulate(duration_s=600, rate_hz=50, **twin.same_unit(run.truth, seed + 1))
    model = CalibratedModel(design, fit.calibration)
    got = accuracy.percentiles(model.predict(check), check.wrench, full_scale(design),
                               (99,))["p99"]
    return np.asarray(fit.diagnosis["on_chip"]["heldout_p99_pct"]), np.asarray(got)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--leads", default="0,0.01,0.02", help="lead times, s (comma list)")
    parser.add_argument("--seeds", type=int, default=4, help="friction units 1..N")
    parser.add_argument("--no-paper", action="store_true", help="skip the paper unit")
    args = parser.parse_args(argv)
    design = load_checked(DEFAULT_DESIGN)
    cases = [("joint_friction", s) for s in range(1, args.seeds + 1)]
    if not args.no_paper:
        cases.append(("paper", 1))
    print("| unit | seed | lead, ms | on-chip prediction p99 | calibrated p99, unseen run "
          "| worst ratio |\n|---|---|---|---|---|---|")
    for lead in (float(v) for v in args.leads.split(",")):
        for scenario, seed in cases:
            predicted, got = case(design, scenario, seed, lead)
            print(f"| {scenario} | {seed} | {1e3 * lead:g} | "
                  + " ".join(f"{v:.2f}" for v in predicted) + " | "
                  + " ".join(f"{v:.2f}" for v in got) + f" | {np.max(got / predicted):.2f} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
