"""Where work runs beyond this process: engines by name, Ray tasks and (live) tracker runners.

The library never imports Ray; :class:`~hrtls.runner.ray_engine.RayEngine` imports it when it is
built (``pip install 'hrtls[ray]'``). The protocol and the local engine are in
:mod:`hrtls.parallel`.
"""

from hrtls.runner.engine import ENGINES, make_engine

__all__ = ["ENGINES", "make_engine"]
