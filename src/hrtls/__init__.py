"""hrtls: Hybrid Rescue Team Localization System.

Pedestrian dead reckoning from one waist-worn IMU, corrected by camera fixes, beacon RSS, passive
RFID tags and ranges to radio nodes, plus self-localization of dropped sensor networks with the
help of moving agents. Conventions (frames, units, quaternion order) are in :mod:`hrtls.frames`.
"""

__version__ = "0.1.0"
