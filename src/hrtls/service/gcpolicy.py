"""Garbage-collector policy of the service process (``hrtls serve``).

Ingest allocates many small containers per batch (decoded lists, validated tuples, futures)
that live for tens of milliseconds: longer than CPython's default young generation (700
allocations, a few milliseconds at hundreds of batches per second), so they are promoted and
the old generation grows fast. Each full collection then walks every object of the process
(the trackers, the modules) and stalls the event loop (measured in docs/scale-out.md). A young
generation of tens of thousands of allocations lets those objects die young, and freezing what
exists after start-up (modules, the application) keeps it out of every later collection.
"""

from __future__ import annotations

import gc

OLD_PER_MIDDLE = 20
"""Young collections per middle-generation collection (CPython: 10)."""


def collect_for_service(young_objects: int) -> None:
    """Freeze what is alive now; collect the young generation every ``young_objects``.

    Call once, in the service process, after start-up (it changes the whole interpreter).
    """
    gc.collect()
    gc.freeze()
    _, _, old = gc.get_threshold()
    gc.set_threshold(young_objects, OLD_PER_MIDDLE, old)
