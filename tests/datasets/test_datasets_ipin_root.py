from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrtls.datasets import default_data_root
from hrtls.datasets.ipin2023 import list_logfiles, load_logfile
from hrtls.errors import InputError


def test_default_data_root_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HRTLS_DATA", str(tmp_path))
    assert default_data_root() == tmp_path
    monkeypatch.setenv("HRTLS_DATA", str(tmp_path / "missing"))
    assert default_data_root() is None


def test_default_data_root_next_to_repo(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("HRTLS_DATA", raising=False)
    expected = Path(__file__).resolve().parents[2].parent / "shared" / "data"
    assert default_data_root() == (expected if expected.is_dir() else None)


def test_missing_folder_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="folder not found"):
        list_logfiles(tmp_path / "nothing")


@pytest.mark.realdata
def test_real_ipin_logfiles(shared_data: Path) -> None:
    names = list_logfiles(shared_data)
    assert names == ["IPIN2023_T3_TrainingTrial04_repetition01.txt",
                     "IPIN2023_T3_TrainingTrial23_repetition03.txt"]
    with pytest.raises(InputError, match="Trial04"):
        load_logfile(shared_data, "nope")
    # 14 and 12 POSI landmarks: the first is the start, the others checkpoints
    for name, n_posi in zip(names, (14, 12), strict=True):
        session = load_logfile(shared_data, name.removesuffix(".txt"))
        assert len(session.landmarks) == 6  # BLE1..BLE6 from BLE_Locations.csv
        assert session.checkpoints is not None and len(session.checkpoints) == n_posi - 1
        assert session.georeference is not None
        acc = session.imu.accel.values  # type: ignore[union-attr]
        assert 9.6 < np.median(np.linalg.norm(acc, axis=1)) < 10.0
