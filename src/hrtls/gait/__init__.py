"""Gait analysis: motion and activity, steps, step length, walking heading and velocity.

One module per algorithm (see ``docs``/ARCHITECTURE):
:mod:`~hrtls.gait.motion_detector` (Basso II-B),
:mod:`~hrtls.gait.cadence` (periodicity walking detection, step frequency),
:mod:`~hrtls.gait.walking_bouts` (walking bouts from step sequences),
:mod:`~hrtls.gait.missed_steps` (one missed step filled in a regular walk),
:mod:`~hrtls.gait.step_length_stride` (stride lengths from steps, turning chord),
:mod:`~hrtls.gait.step_length_pendulum` (inverted-pendulum step length),
:mod:`~hrtls.gait.turns` (turn segmentation on the vertical-axis rate),
:mod:`~hrtls.gait.activity_tree` and :mod:`~hrtls.gait.activity_lda` (Inderst 4.1),
:mod:`~hrtls.gait.pll` (Basso II-C), :mod:`~hrtls.gait.peak_steps` (Inderst 4.3.1, Tarrio III-B),
:mod:`~hrtls.gait.step_length` and :mod:`~hrtls.gait.step_length_fit` (Weinberg, Basso II-D,
Inderst eq. 4.25), :mod:`~hrtls.gait.fourier_heading` (Basso III),
:mod:`~hrtls.gait.walking_direction` (walking direction from the motion, mounting unknown),
:mod:`~hrtls.gait.velocity_automaton` (Colombo III-C), :mod:`~hrtls.gait.vertical` (levelling)
and :mod:`~hrtls.gait.analyzer` (:class:`GaitAnalyzer`, composing them, with its parts
:mod:`~hrtls.gait.step_heading`, :mod:`~hrtls.gait.step_release`,
:mod:`~hrtls.gait.window_activity` and :mod:`~hrtls.gait.analyzer_state`);
:mod:`~hrtls.gait.session_analysis` runs it over a whole session.
"""

from hrtls.gait.activity_lda import LdaModel, train_lda
from hrtls.gait.activity_tree import TreeThresholds, calibrate_tree, classify_tree
from hrtls.gait.analyzer import GaitAnalyzer, GaitResult
from hrtls.gait.cadence import CadenceDetector, CadenceParams
from hrtls.gait.fourier_heading import FourierHeading, FourierHeadingParams
from hrtls.gait.missed_steps import MissedStepFiller, MissedStepParams
from hrtls.gait.motion_detector import MotionDetector, MotionParams
from hrtls.gait.peak_steps import PeakStepDetector, PeakStepParams
from hrtls.gait.pll import PllParams, PllStepDetector, StepDetection
from hrtls.gait.session_analysis import activity_windows, analyze_session, session_inputs
from hrtls.gait.step_length import (
    FrequencyLawModel,
    StairsModel,
    WeinbergModel,
    displacements,
    step_model_from_dict,
)
from hrtls.gait.step_length_fit import (
    CalibrationWalk,
    fit_frequency_law,
    fit_pendulum,
    fit_weinberg,
    fit_weinberg_running,
    walks_between_marks,
)
from hrtls.gait.step_length_pendulum import PendulumModel, vertical_excursion
from hrtls.gait.step_length_stride import chord_factor, prorated_stride_lengths
from hrtls.gait.turns import TurnDetector, TurnEvents, TurnParams
from hrtls.gait.velocity_automaton import AutomatonParams, VelocityAutomaton
from hrtls.gait.vertical import GravityLevelling, LevelledAcceleration, from_orientation
from hrtls.gait.walking_bouts import WalkingBoutDetector, WalkingBoutParams, walking_bouts

__all__ = [
    "AutomatonParams",
    "CadenceDetector",
    "CadenceParams",
    "CalibrationWalk",
    "FourierHeading",
    "FourierHeadingParams",
    "FrequencyLawModel",
    "GaitAnalyzer",
    "GaitResult",
    "GravityLevelling",
    "LdaModel",
    "LevelledAcceleration",
    "MissedStepFiller",
    "MissedStepParams",
    "MotionDetector",
    "MotionParams",
    "PeakStepDetector",
    "PeakStepParams",
    "PendulumModel",
    "PllParams",
    "PllStepDetector",
    "StairsModel",
    "StepDetection",
    "TreeThresholds",
    "TurnDetector",
    "TurnEvents",
    "TurnParams",
    "VelocityAutomaton",
    "WalkingBoutDetector",
    "WalkingBoutParams",
    "WeinbergModel",
    "activity_windows",
    "analyze_session",
    "calibrate_tree",
    "chord_factor",
    "classify_tree",
    "displacements",
    "fit_frequency_law",
    "fit_pendulum",
    "fit_weinberg",
    "fit_weinberg_running",
    "from_orientation",
    "prorated_stride_lengths",
    "session_inputs",
    "step_model_from_dict",
    "train_lda",
    "vertical_excursion",
    "walking_bouts",
    "walks_between_marks",
]
