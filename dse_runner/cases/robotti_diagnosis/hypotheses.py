"""The library of missing-physics hypotheses diagnosis chooses from.

Each hypothesis has a stable id, a physical name, a paragraph on the physics,
the residual signature it leaves, and its parameterised model: parameters of
the vehicle's effects variant (``bundled:fmus/robotti_vehicle_effects``), each zero
when the effect is absent, so that every hypothesis, and every combination of
them, is one point of one multi-model. ``none`` has no parameters: the
residual is receiver noise.
"""

from __future__ import annotations

from ...analysis.diagnose.hypotheses import EffectParameter, Hypothesis
from ...errors import DseError

EFFECTS_FMU = "bundled:fmus/robotti_vehicle_effects"  # the variant's C sources, shipped in the package


def _p(variable: str, unit: str, lower: float, upper: float, step: float) -> EffectParameter:
    return EffectParameter(variable=variable, unit=unit, lower=lower, upper=upper, step=step)


LIBRARY: dict[str, Hypothesis] = {
    h.id: h
    for h in [
        Hypothesis(
            id="wheel_slip",
            name="longitudinal wheel slip on soil (terramechanics)",
            explanation=(
                "On soft or loose soil a driven wheel shears the ground under it, so the vehicle moves more "
                "slowly than its wheels turn: ground speed = (1 - i) x wheel speed, with the slip ratio i "
                "set by the soil's shear strength and the drawbar pull (Wong, Theory of Ground Vehicles). "
                "The drive regulates wheel speed to the command, so the vehicle covers less ground than "
                "the model, and as commands are replayed in time it turns at the wrong places."
            ),
            signature="along-track error that grows in proportion to the distance travelled, in every run",
            parameters=(_p("wheel_slip", "1", 0.0, 0.5, 0.005),),
            magnitude_unit="slip ratio",
        ),
        Hypothesis(
            id="steering_lag",
            name="steering actuator lag",
            explanation=(
                "The steering actuator turns the wheels at a finite rate, modelled as a first-order lag "
                "with time constant tau between the commanded and the actual wheel angle. The vehicle "
                "turns later and less sharply than commanded whenever the steering command changes."
            ),
            signature=(
                "cross-track error that grows while the steering "
                "angle changes (correlates with steering rate)"
            ),
            parameters=(_p("steering_lag", "s", 0.0, 3.0, 0.02),),
            magnitude_unit="s",
        ),
        Hypothesis(
            id="speed_lag",
            name="speed actuator lag",
            explanation=(
                "The drive train (hydraulic or electric) follows the speed set-point with a first-order lag "
                "of time constant tau on top of the speed controller, so the vehicle reaches a new speed "
                "later than the model."
            ),
            signature=(
                "along-track error that grows during acceleration "
                "and braking and stops growing at constant speed"
            ),
            parameters=(_p("speed_lag", "s", 0.0, 5.0, 0.02),),
            magnitude_unit="s",
        ),
        Hypothesis(
            id="steering_offset",
            name="steering offset",
            explanation=(
                "A misaligned steering linkage or sensor zero makes the wheels point at a constant angle "
                "when the command is straight ahead: the actual angle is the command plus an offset."
            ),
            signature="cross-track error that grows steadily on straight segments, always to the same side",
            parameters=(_p("steering_offset", "rad", -0.2, 0.2, 0.001),),
            magnitude_unit="rad",
        ),
        Hypothesis(
            id="time_offset",
            name="time offset between the control log and the GPS log",
            explanation=(
                "The two logs run on different clocks, or the GPS fix carries latency: the vehicle appears "
                "to act on each command some time after the control log says. Modelled as a pure delay of "
                "the replayed commands (the vehicle is at rest before the first one)."
            ),
            signature=(
                "errors at every change of speed or steering, in both "
                "along- and cross-track, as if the run were shifted in time"
            ),
            parameters=(_p("time_offset", "s", 0.0, 3.0, 0.02),),
            magnitude_unit="s",
        ),
        Hypothesis(
            id="antenna_offset",
            name="GPS antenna lever arm",
            explanation=(
                "The GPS antenna is not at the model's reference point (mid-way between the axles) but at a "
                "lever arm (forward, left) from it, so the recorded track is the reference point's track "
                "displaced by the lever arm rotated with the heading."
            ),
            signature=(
                "an offset constant in the vehicle frame from the "
                "first fix on: along-track bias, cross-track bias"
            ),
            parameters=(_p("antenna_x", "m", -3.0, 3.0, 0.02), _p("antenna_y", "m", -3.0, 3.0, 0.02)),
            magnitude_unit="m",
        ),
        Hypothesis(
            id="terrain_slope",
            name="terrain slope",
            explanation=(
                "The field is not level: gravity's component along a plane rising by grade_x per metre east "
                "and grade_y per metre north pulls the vehicle downhill, slowing it uphill, speeding it "
                "downhill and pushing it sideways across the slope, by amounts that depend on its heading."
            ),
            signature="along- and cross-track error whose sign and rate depend on the heading",
            parameters=(_p("grade_x", "1", -0.3, 0.3, 0.002), _p("grade_y", "1", -0.3, 0.3, 0.002)),
            magnitude_unit="grade",
        ),
        Hypothesis(
            id="none",
            name="the residual is noise",
            explanation=(
                "The calibrated baseline explains the recordings as well as any candidate effect does on "
                "runs it was not fitted to: what remains is receiver noise and unmodelled detail too small "
                "to name. Nothing is added to the model."
            ),
            signature="residuals without structure: no growth, no correlation with the vehicle's motion",
        ),
    ]
}


# Effects whose residual signatures are alike on ordinary manoeuvres, so a fit can take one for the other: a
# delay of every command against a steering lag or a speed lag, slip (attenuation, no phase) against a speed
# lag (phase, no steady error). The screen fits a shortlisted set's twins beside it, so the evidence between
# them comes from real fits, not from a linearisation's ranking.
LOOK_ALIKES: dict[str, tuple[str, ...]] = {
    "time_offset": ("steering_lag", "speed_lag"),
    "steering_lag": ("time_offset",),
    "wheel_slip": ("speed_lag",),
    "speed_lag": ("wheel_slip", "time_offset"),
}


def hypothesis(hid: str) -> Hypothesis:
    if hid not in LIBRARY:
        raise DseError(f"unknown hypothesis {hid!r}: the library has {', '.join(LIBRARY)}")
    return LIBRARY[hid]


def effect_variables() -> list[str]:
    """Every effect parameter of the library, in library order."""
    return [v for h in LIBRARY.values() for v in h.variables]
