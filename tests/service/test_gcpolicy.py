"""The service process's garbage-collector policy."""

from __future__ import annotations

import gc

from hrtls.service.gcpolicy import OLD_PER_MIDDLE, collect_for_service
from hrtls.service.settings import Settings


def test_service_freezes_start_up_objects_and_collects_young_less_often() -> None:
    before = gc.get_threshold()
    try:
        collect_for_service(Settings().gc_young_objects)
        young, middle, old = gc.get_threshold()
        assert young == Settings().gc_young_objects >= 10_000
        assert (middle, old) == (OLD_PER_MIDDLE, before[2])
        assert gc.get_freeze_count() > 1000
    finally:
        gc.unfreeze()
        gc.set_threshold(*before)
