"""Compile the numerical kernels once, where a pip install can keep them.

The kernels are numba functions with ``cache=True``: compiled on first use and cached beside
the package's sources, or under ``NUMBA_CACHE_DIR``. :func:`configure_cache` points
``NUMBA_CACHE_DIR`` at a user folder (``$XDG_CACHE_HOME/hrtls/numba``, else
``~/.cache/hrtls/numba``) when the package folder is not writable (a system-wide install), and
must run before numba is imported. :func:`warm_up` tracks the simulated two-floor walk with
every preset, which compiles what ``hrtls track`` and ``hrtls demo`` use, and leaves a marker
so that the first-run notice (:func:`first_run`) is not shown again.
"""

from __future__ import annotations

import os
import time
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import hrtls

NOTICE = ("first run after install: compiling the numerical kernels once (a minute or two); "
          "later runs start at once. `hrtls warmup` does it ahead.")


def cache_root() -> Path:
    """User cache folder of hrtls."""
    base = os.environ.get("XDG_CACHE_HOME")
    return (Path(base) if base else Path.home() / ".cache") / "hrtls"


def configure_cache() -> Path | None:
    """Set ``NUMBA_CACHE_DIR`` to the user cache when the package folder is read-only.

    Returns the folder set, or None when the kernels are cached beside the sources (or
    ``NUMBA_CACHE_DIR`` was already set).
    """
    if "NUMBA_CACHE_DIR" in os.environ:
        return None
    package = Path(hrtls.__file__).resolve().parent
    if os.access(package, os.W_OK):
        return None
    folder = cache_root() / "numba"
    folder.mkdir(parents=True, exist_ok=True)
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    return folder


def _numba_version() -> str:
    """The installed numba version, read from its distribution folder (numba is not imported)."""
    import importlib.util

    spec = importlib.util.find_spec("numba")
    if spec is None or spec.origin is None:
        return "none"
    site = Path(spec.origin).parent.parent
    found = sorted(site.glob("numba-*.dist-info"))
    return found[0].name[len("numba-"):-len(".dist-info")] if found else "unknown"


def compiled_marker() -> Path:
    """The file whose presence says the kernels of this install and cache are compiled."""
    where = os.environ.get("NUMBA_CACHE_DIR", str(Path(hrtls.__file__).resolve().parent))
    tag = f"{hrtls.__version__}-numba{_numba_version()}-{zlib.crc32(where.encode()):08x}"
    return cache_root() / f"compiled-{tag}"


def first_run() -> bool:
    """True when the kernels have not been compiled for this install yet."""
    return not compiled_marker().exists()


def mark_compiled() -> None:
    """Remember that the kernels are compiled (after a run that compiled them)."""
    marker = compiled_marker()
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.write_text(f"{time.time():.0f}\n", encoding="utf-8")
    except OSError:
        pass  # an unwritable home: the notice shows again, nothing else changes


def warm_up(progress: Callable[[str], None] | None = None) -> float:
    """Compile the kernels by tracking a simulated walk with every preset; seconds taken."""
    import warnings

    from hrtls.fusion.fixes import partial_step_xy
    from hrtls.kernels import jit_only
    from hrtls.pipeline import Tracker, preset
    from hrtls.pipeline.config import PRESETS
    from hrtls.pipeline.finish import finish_track
    from hrtls.sim.scenarios import run_scenario

    jit_only()  # the builds compiled ahead of time are made from what the JIT compiles here
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if progress:
            progress("simulating a short walk")
        session = run_scenario("inderst_multifloor", 0).session
        for name in PRESETS:
            if progress:
                progress(f"compiling for preset {name}")
            cfg = preset(name)
            finish_track(Tracker(cfg).run(session), session, cfg)
        if progress:
            progress("compiling for tags, fixes and a device orientation")
        cfg = preset("default")
        for other in _more_sessions(session):
            finish_track(Tracker(cfg).run(other), other, cfg)
        partial_step_xy(0.5, 0.0, 1.0, 0.7, 0.0)  # a fix within a step: rare in short walks
    mark_compiled()
    return time.perf_counter() - start


def _more_sessions(session: Any) -> list[Any]:
    """Sessions that reach the kernels the presets' walk does not (for the builds ahead of time).

    A short office walk (tags, fixes, beacons) and ``session`` with a device orientation (the
    compass correction; identity quaternions: only the argument types matter here).
    """
    import dataclasses

    import numpy as np

    from hrtls.data import OrientationSeries
    from hrtls.sim.scenarios import run_scenario

    t = session.imu.accel.t
    q = np.zeros((len(t), 4))
    q[:, 0] = 1.0
    device = dataclasses.replace(session, orientation=OrientationSeries(t=t, q=q))
    return [run_scenario("office_random_walk", 0, duration_s=600.0).session, device]


def build_ahead() -> str:
    """Compile the kernels that :func:`warm_up` compiled ahead of time; one line saying how."""
    import warnings

    from hrtls.jobs.aot import build
    from hrtls.kernels import folder

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            count = build()
    except Exception as exc:  # no C compiler, or pycc failed: the JIT kernels serve
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        reason = reason.split(". ")[0].rstrip(".")[:160]  # its first sentence
        return f"kernels not compiled ahead of time ({reason}); the JIT kernels are used"
    return f"{count} kernel builds compiled ahead of time into {folder()}"
