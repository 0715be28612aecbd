"""The Robotti's hypothesis library as a plug-in of ``diagnose`` (entry-point
group ``dse_runner.hypotheses``).

Why a plug-in: the field robot's effects (wheel slip, actuator lags, steering and time offsets, the
antenna lever arm, terrain slope, and the correction block discovery fits) live in its own effects FMU
and are judged in GPS units; the diagnosis core knows none of that and reaches it only through this
class. It serves any space whose runs are field data (GPS fixes), which is what ``diagnose --scenarios
DIR`` gives when it fills the bundled calibration space with the runs in DIR.
"""

from __future__ import annotations

from ...analysis.diagnose.answer import Answer
from ...analysis.diagnose.hypotheses import Hypothesis
from ...analysis.diagnose.library import HypothesisLibrary, Messages, Request
from ...analysis.diagnose.report import Section
from ...sweeps.spec import Space
from .. import fielddata
from . import report
from .hypotheses import LIBRARY
from .outcome import SCREEN, Diagnosis, DiagnosisSettings
from .workflow import DEFAULT_SPACE, diagnose_calibration


class RobottiLibrary(HypothesisLibrary):
    """Wheel slip, actuator lags, offsets, lever arm, slope and the discovered correction, on GPS fixes."""

    name = Diagnosis.library_name
    calibration = DEFAULT_SPACE
    screen = SCREEN

    def serves(self, space: Space) -> bool:
        return bool(space.scenarios) and all(s.kind == fielddata.KIND for s in space.scenarios)

    def diagnose(self, space: Space, request: Request, say: Messages) -> Diagnosis:
        settings = DiagnosisSettings(
            folds=request.folds,
            hypotheses=request.hypotheses,
            noise_factor=request.noise_factor,
            discovery=request.discovery,
            screen=self.screen_for(request),
        )
        return diagnose_calibration(space, settings, progress=say)

    def sections(self, answer: Answer) -> list[Section]:
        return report.sections(answer)

    def hypotheses(self, space: Space) -> list[Hypothesis]:
        return [h for h in LIBRARY.values() if h.id != "none"]
