"""The mismatch tool: locate, name and model physics a simulation leaves out.

Python API::

    from hyst_gym.diagnose import diagnose, read_recording, make_recording
    report = diagnose("recording.csv", model="lumped")   # -> Report
    report.verdict, report.confidence, report.explanation, report.to_json()

Command line: ``hyst-gym diagnose RECORDING.csv [--model ...] [--json R.json] [--plots DIR]`` and
``hyst-gym make-recording --effect ID --seed S [--strength X] [--output ...] --out FILE.csv``.
"""

from .pipeline import diagnose
from .results import Report
from .make_recording import GENERATOR_EFFECTS, make_recording
from .effects import EFFECTS
from .recording import Recording, read_recording, write_recording
from .report import write_json, write_plots

__all__ = ["EFFECTS", "GENERATOR_EFFECTS", "Recording", "Report", "diagnose", "make_recording",
           "read_recording", "write_json", "write_plots", "write_recording"]
