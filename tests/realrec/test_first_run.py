"""The first run says that it compiles once; the marker silences it; a read-only install caches
in the user's folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.io.session import write_session
from hrtls.jobs import warmup


def test_marker_and_cache_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", "recorded")  # so that teardown restores it
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert warmup.first_run()
    warmup.mark_compiled()
    assert not warmup.first_run()
    monkeypatch.setattr(warmup.os, "access", lambda *_: False)  # a read-only site-packages
    folder = warmup.configure_cache()
    assert folder == tmp_path / "cache" / "hrtls" / "numba" and folder.is_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == str(folder)
    assert warmup.configure_cache() is None  # already set: left alone


def test_track_announces_the_first_compilation_once(tmp_path: Path) -> None:
    t = np.arange(500) * 0.01
    session = tmp_path / "s"
    write_session(Session(imu=ImuStream(SensorSeries(t, np.tile([0.0, 0.0, 9.81], (500, 1)),
                                                     "acc"))), session)
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    cmd = [sys.executable, "-c", "from hrtls.cli.app import main; main()", "track",
           str(session), "-o"]
    first = subprocess.run([*cmd, str(tmp_path / "o1")], env=env, capture_output=True,
                           text=True, check=True)
    assert "compiling the numerical kernels once" in first.stderr
    second = subprocess.run([*cmd, str(tmp_path / "o2")], env=env, capture_output=True,
                            text=True, check=True)
    assert "compiling" not in second.stderr
