"""Shared fixtures: the real recordings in ``../shared/data`` (skipped when absent)."""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
# the tests call the JIT kernels (the reference), whatever `hrtls warmup` built ahead of time;
# tests/test_kernels_aot.py builds and checks its own
os.environ.setdefault("HRTLS_AOT", "0")
# no background compile process from a demo the tests start (tests/test_kernel_builds.py checks it)
os.environ.setdefault("HRTLS_PRECOMPILE", "0")


def shared_data_root() -> Path | None:
    """Folder of the real recordings, or None (env HRTLS_DATA overrides ../shared/data)."""
    env = os.environ.get("HRTLS_DATA")
    candidate = Path(env) if env else REPO_ROOT.parent / "shared" / "data"
    return candidate if candidate.is_dir() else None


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ../shared/data; skips the test when the recordings are not on this machine."""
    root = shared_data_root()
    if root is None:
        pytest.skip("real recordings (../shared/data) are not available on this machine")
    return root


@pytest.fixture(scope="module")
def benchmark_import() -> Iterator[Callable[[str], ModuleType]]:
    """Imports a module of ``benchmarks/``; the folder stays on ``sys.path`` for the test
    module (a process pool spawned by a test imports the same modules)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(REPO_ROOT / "benchmarks"))
        yield importlib.import_module
