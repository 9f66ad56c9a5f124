"""The tracker: wires attitude, gait and fusion from a configuration (offline and live)."""

from hrtls.pipeline.config import PRESETS, TrackerConfig, load_config, preset
from hrtls.pipeline.tracker import Tracker, TrackResult

__all__ = ["PRESETS", "TrackResult", "Tracker", "TrackerConfig", "load_config", "preset"]
