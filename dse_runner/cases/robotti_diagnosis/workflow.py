"""The diagnosis workflow: calibrate, locate, explain with the library, screen combinations, discover beyond
it, and write the model."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...analysis.diagnose import discovery, explain, screens
from ...analysis.diagnose.calibration import searched
from ...analysis.diagnose.choice import choose, screen_of
from ...analysis.diagnose.explain import Candidate
from ...analysis.diagnose.library import space_with
from ...analysis.diagnose.one_thread import one_thread
from ...analysis.diagnose.validation import Validation, validated
from ...errors import DseError
from ...simulation.scenario import dropouts
from ...sweeps.cluster import connect
from ...sweeps.spec import Space
from ...sweeps.sweep import trajectories_of
from . import correction, discover, locate, lookalike, noise
from .chain import Chain, DiagnosisMessages
from .model_files import base_parameters, fits_space, steering_source, vehicle_of, write_model
from .noise import NoiseFloor
from .outcome import Diagnosis, DiagnosisSettings

DEFAULT_SPACE = "bundled:robotti/calibration.yaml"  # the Robotti baseline's calibration grid
DEFAULT_SETTINGS = DiagnosisSettings()  # frozen, so one instance serves every call
BEFORE, AFTER = "diagnosis-before", "diagnosis-after"  # sweeps holding the tracks of the report


FIX_COLUMNS = ("x", "y")  # a run's recorded GPS fixes (fielddata.py): what a time block holds out


def recorded(space: Space, validation: Validation) -> Space:
    """``space`` with only the recorded runs, without the views a time-block validation adds: what the
    residuals are located on, look-alikes weighed on and discovery observes."""
    runs = [s for s in space.scenarios if s.name in validation.fitted]
    return space.with_scenarios(runs)


def _locate(space: Space, vehicle: str, tracks: dict[str, Any]) -> Any:
    import pandas as pd

    signals = locate.Signals(
        f"{vehicle}.gps_x",
        f"{vehicle}.gps_y",
        f"{vehicle}.theta",
        f"{vehicle}.vx",
        f"{vehicle}.yaw_rate",
        steering_source(space.multimodel, vehicle),
    )
    return pd.concat(
        [locate.residual_frame(tracks[s.name], s, signals) for s in space.scenarios], ignore_index=True
    )


def seek(
    chain: Chain, reference: Candidate, candidates: list[Candidate], floor: NoiseFloor, space: Space
) -> discovery.Discovery | None:
    """The engine's discovery (analysis/diagnose/discovery.py) with the correction block's terms
    (discover/search.py) on top of the library's answer, only when that answer leaves held-out error above
    ``noise_factor`` noise floors: below it there is nothing a correction could claim but noise. Without a
    floor nothing counts as above it, so nothing is sought."""
    settings = chain.settings
    if not (
        floor.available
        and explain.above_floor(reference.cross_validated, floor.cross_track, settings.noise_factor)
    ):
        return None
    chain.say(
        f"the library leaves {reference.cross_validated:.4f} m held-out "
        f"({reference.cross_validated / floor.cross_track:.1f}x the noise floor): seeking a correction"
    )
    search = discover.CorrectionSearch(
        chain,
        chain.vehicle,
        [discover.observe(s) for s in space.scenarios],
        space.multimodel.parameters,
        settings.max_terms,
    )
    found = discovery.discover(
        chain, search, reference, candidates, settings.min_gain, settings.bic_margin, unit=" m"
    )
    if found.chosen is not None:
        effects = {hid: effect.parameters for hid, effect in chain.library.items()}
        found.resembles = discovery.resembles(chain, search, found.chosen, effects)
        chain.say(
            f"discovered {'; '.join(correction.readable(found.chosen.full.point))}: held-out "
            f"{reference.cross_validated:.4f} -> {found.chosen.cross_validated:.4f} m"
        )
    else:
        chain.say(f"nothing discovered: {found.reason}")
    return found


def diagnose(
    scenarios: str | Path,
    multimodel: str | Path | None = None,
    space: str | Path | None = None,
    out: str | Path | None = None,
    settings: DiagnosisSettings = DEFAULT_SETTINGS,
    client=None,
    progress: DiagnosisMessages | None = None,
    n_workers: int | None = None,
    address: str | None = None,
) -> Diagnosis:
    """Calibrate -> locate -> explain -> model -> re-calibrate on a folder of recorded runs.

    ``space`` gives the calibration's parameters and ranges (default: the bundled Robotti
    calibration, bundled:robotti/calibration.yaml); ``multimodel`` replaces its multi-model."""
    settings.singles()  # an unknown hypothesis is named before anything runs
    out = Path(out or "out/diagnosis").resolve()
    calibration = space_with(space or DEFAULT_SPACE, scenarios, out, multimodel, n_workers, address)
    return diagnose_calibration(calibration, settings, client, progress)


@one_thread
def diagnose_calibration(
    calibration: Space,
    settings: DiagnosisSettings = DEFAULT_SETTINGS,
    client=None,
    progress: DiagnosisMessages | None = None,
) -> Diagnosis:
    """The whole chain on a calibration space whose scenarios are recorded runs in the field-data format,
    its results (and the new model and report) in the space's output folder."""
    settings.singles()
    say = progress or (lambda message: None)
    out = Path(calibration.output)
    if client is None:
        with connect(calibration.spec.cluster, calibration.path.parent) as own:
            return _diagnose(calibration, out, settings, own, say)
    return _diagnose(calibration, out, settings, client, say)


def _diagnose(
    calibration: Space, out: Path, settings: DiagnosisSettings, client, say: DiagnosisMessages
) -> Diagnosis:
    from . import report

    floor = noise.estimate_noise(calibration.scenarios)  # from the files alone, before any model is fitted
    if floor.available:
        say(
            f"noise floor: GPS sigma {floor.sigma:.4f} m ({floor.method}, {floor.fixes} fixes), "
            f"{floor.cross_track:.4f} m of cross-track error"
        )
    grid = searched(calibration, client, say)
    if grid is None:
        raise DseError(
            f"{calibration.path}: nothing to search (no parameter, or its points given as they are); the "
            "Robotti's diagnosis calibrates from a search of its parameters' ranges, such as a grid"
        )
    vehicle = vehicle_of(calibration)
    base = base_parameters(calibration, grid.best)
    space, validation = validated(fits_space(calibration, vehicle, out), settings.folds, list(FIX_COLUMNS))
    say(validation.text)
    chain = Chain.for_vehicle(space, vehicle, base, client, settings, say, validation, grid.best)
    space = recorded(space, validation)  # the runs themselves: what is located, weighed and observed
    choice = choose(
        chain,
        screens.strategy(settings.screen),
        settings.screen_settings(),
        floor.cross_track if floor.available else None,
        settings.noise_factor,
        settings.floor_stop,
        settings.max_effects,
    )
    baseline = choice.baseline
    chosen, looks = lookalike.weigh(
        choice.chosen,
        choice.everything,
        baseline,
        space.scenarios,
        floor.sigma if floor.available else None,
        settings.min_gain,
        settings.bic_margin,
    )
    # the noise rule: a member is claimed only if it changes the held-out error by more than the noise does
    chosen, dropped = (
        explain.claimed(chosen, choice.everything, baseline, floor.cross_track)
        if floor.available
        else (chosen, [])
    )
    if dropped:
        say(
            "not claimed (each changes the held-out error by less "
            f"than the noise): {', '.join(d.id for d in dropped)}"
        )
    found = seek(chain, chosen, choice.everything, floor, space) if settings.discovery else None
    if found is not None and found.chosen is not None:  # discovered terms face the noise rule too
        chosen, more = explain.claimed(
            found.chosen, [*choice.everything, *found.candidates], baseline, floor.cross_track
        )
        if more:
            say(f"not claimed (changes the held-out error by less than the noise): {more[0].id}")
        dropped += more
    diagnosis = Diagnosis(
        out,
        {
            "sweep": calibration.name,
            "vehicle": vehicle,
            "grid_best": grid.best,
            "grid_at_bound": [
                p.name
                for p in base
                if grid.best[p.name] in (p.lower, p.upper) and p.name not in baseline.full.undetermined
            ],
            "refined": baseline.full.values,
            "refined_at_bound": baseline.full.at_bound,
            "no_effect": baseline.full.undetermined,
            "insensitive_scenarios": locate.insensitive_scenarios(grid.table1),
            "folds": validation.tests,
            "validation": validation.to_json(),
            "groups": {s.name: s.group for s in calibration.scenarios},
        },
        settings,
        baseline=baseline,
        chosen=chosen,
        candidates=explain.ranked(choice.everything + (found.candidates if found else [])),
        space=calibration.name,
        validation=validation,
        dropouts=dropouts(calibration.scenarios),
        floor=floor,
        screen=screen_of(choice),
        growth=choice.growth,
        lookalikes=looks,
        discovery=found,
        dropped=dropped,
    )
    say("locating: the residuals of the calibrated model and of the chosen one")
    before = trajectories_of(space, client, baseline.full.point, BEFORE)
    lookalike.attach_responses(
        looks,
        space.scenarios,
        before,
        {"heading": f"{vehicle}.theta", "vx": f"{vehicle}.vx", "vy": f"{vehicle}.vy"},
    )
    after = trajectories_of(space, client, chosen.full.point, AFTER)
    frames = {"before": _locate(space, vehicle, before), "after": _locate(space, vehicle, after)}
    diagnosis.located = locate.located(frames)
    diagnosis.files.update(write_model(diagnosis, calibration))
    diagnosis.files.update(report.write(diagnosis, space, frames, before, after))
    return diagnosis
