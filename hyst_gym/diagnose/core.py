"""Former home of the pipeline, kept so that existing imports work.

The stages now live by job: :mod:`.pipeline` (``diagnose``), :mod:`.results` (``Candidate``,
``Report``), :mod:`.hypothesize` (calibration and candidate fits), :mod:`.priors`,
:mod:`.continuum` and :mod:`.locate`. New code imports from those.
"""

from .continuum import first_resonance_hz, resonance_power_share, try_continuum
from .hypothesize import (HYSTERESIS_NAMES, MAINS_FREQUENCIES, calibrate, cross_start, fit_candidate, in_threads,
                          loop_informed_starts, mains_starts)
from .locate import locate_mismatch, window_refits
from .pipeline import DEFAULT_WORKERS, diagnose
from .priors import PRIOR_PARAMETERS, RELEASED_TOLERANCE, release_prior
from .report import physical_params
from .results import Candidate, Report

__all__ = ["Candidate", "DEFAULT_WORKERS", "HYSTERESIS_NAMES", "MAINS_FREQUENCIES", "PRIOR_PARAMETERS",
           "RELEASED_TOLERANCE", "Report", "calibrate", "cross_start", "diagnose", "first_resonance_hz",
           "fit_candidate", "in_threads", "locate_mismatch", "loop_informed_starts", "mains_starts",
           "physical_params", "release_prior", "resonance_power_share", "try_continuum", "window_refits"]
