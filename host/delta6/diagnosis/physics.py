"""Fitted parameters that physics does not allow: a negative friction, play, compliance or
latency means the term fitted something else (another effect, noise), so it is reported with
a warning instead of being taken at face value."""
from __future__ import annotations

#: Summaries of each effect that cannot be negative (names or name prefixes of its params).
NON_NEGATIVE = {
    "joint_friction": ("coulomb_equiv_nm", "viscous_equiv_nm_s_per_rad"),
    "spring_hysteresis": ("loop_half_width_nm",),
    "backlash": ("play_rad",),
    "link_compliance": ("axial_", "bending_"),
    "sensor_latency": ("latency_s",),
}


#: A viscous friction fitted negative on every joint, in proportion to the joints' spring
#: rates, is what a reference sensor paired with the encoders late looks like: the lag L
#: turns the spring torque k * theta into k * theta(t - L), about k * theta - k * L * theta'.
LAGGING = ("viscous_equiv_nm_s_per_rad",)


def warnings(effect: str, params: dict, spring_rates=None) -> list[str]:
    """One line per parameter of ``effect`` whose fitted value is negative where physics
    allows only zero or more (``spring_rates``, N*m/rad per joint: to say how late a
    reference would be that a negative viscous term on every joint stands in for)."""
    out = []
    for name, value in params.items():
        if not any(name == k or (k.endswith("_") and name.startswith(k))
                   for k in NON_NEGATIVE.get(effect, ())):
            continue
        values = value if isinstance(value, list) else [value]
        bad = [(i, v) for i, v in enumerate(values) if v < 0]
        if bad:
            where = ", ".join((f"j{i + 1} " if len(values) > 1 else "") + f"{v:.3g}"
                              for i, v in bad)
            # Per joint, a family of several often takes a neighbour's part there (friction,
            # hysteresis and backlash trade): the effect may still be there on the others.
            line = (f"{effect}: {name} fitted negative ({where}): not physical; "
                    + ("there the term trades with a neighbouring family or stands in for "
                       "something else" if len(bad) < len(values) else
                       "the term stands in for something else"))
            lag = (sorted(-v / k for v, k in zip(values, spring_rates))
                   if name in LAGGING and len(bad) == len(values) == 6
                   and spring_rates is not None else None)
            if lag and lag[-1] <= 2 * lag[0]:       # one lag for every joint
                line += (f", as a reference paired with the encoders about "
                         f"{1e3 * (lag[2] + lag[3]) / 2:.0f} ms late would (viscous = -k x "
                         "the lag; delta6 calibrate fits the rig's latency apart)")
            out.append(line)
    return out
