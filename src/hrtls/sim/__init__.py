"""Synthetic data: walking motion, waist gait, IMU and infrastructure models, named scenarios.

``hrtls.sim`` is a tool around the pipeline (ARCHITECTURE.md): it may import ``hrtls.data`` and
``hrtls.io`` but the pipeline never imports it.
"""
