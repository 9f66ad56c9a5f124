"""The batch wire format: rows and binary column blocks, every refusal, pickling, tracker input."""

from __future__ import annotations

import pickle
from typing import Any

import httpx
import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from tests.service.conftest import Live, new_agent, new_mission
from tests.service.streams import API

from hrtls.data.session import SessionMeta
from hrtls.service.batches import BatchError, decode_body, parse_batch, to_chunk
from hrtls.service.columns import MAX_SAMPLES, block


def _imu(n: int, t0: float = 10.0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(n)
    return {"t": t0 + 0.01 * np.arange(n), "acc": rng.normal(0, 3, (n, 3)),
            "gyr": rng.normal(0, 1, (n, 3)), "mag": rng.normal(0, 30, (n, 3))}


def _batch(*, blocks: bool, n: int = 5) -> dict[str, Any]:
    imu = _imu(n)
    col = block if blocks else (lambda a: a.tolist())
    return {"seq": 3,
            "imu": {k: col(v) for k, v in imu.items()},
            "baro": {"t": col(np.array([10.0])), "p_pa": col(np.array([101000.0]))},
            "rss": {"t": col(np.array([10.0, 10.0])), "anchor": ["B1", "B2"],
                    "rss_dbm": col(np.array([-70.0, -81.5]))},
            "tags": {"t": col(np.array([10.02])), "tag": ["T3"]},
            "ranges": {"t": col(np.array([10.0, 10.01])), "node": ["N1", "N2"],
                       "range_m": col(np.array([4.2, 7.0])),
                       "sigma_m": block(np.array([0.3, np.nan])) if blocks else [0.3, None]},
            "fixes": {"t": col(np.array([10.03])), "x": col(np.array([1.0])),
                      "y": col(np.array([2.0])), "z": None, "sigma_m": col(np.array([0.5]))}}


def _parse_msgpack(value: dict[str, Any]) -> Any:
    return parse_batch(decode_body(msgpack.packb(value), "application/msgpack"))


def _same_chunk(a: Any, b: Any) -> None:
    for name in ("imu", "pressure", "rss", "tags", "ranges", "fixes"):
        pa, pb = getattr(a, name), getattr(b, name)
        assert (pa is None) == (pb is None), name
    ta, tb = a.imu.aligned(), b.imu.aligned()
    for x, y in zip(ta, tb, strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.pressure.values, b.pressure.values)
    np.testing.assert_array_equal(a.rss.anchor, b.rss.anchor)
    np.testing.assert_array_equal(a.rss.rss_dbm, b.rss.rss_dbm)
    np.testing.assert_array_equal(a.tags.tag, b.tags.tag)
    np.testing.assert_array_equal(a.ranges.sigma_m, b.ranges.sigma_m)
    np.testing.assert_array_equal(a.fixes.xyz, b.fixes.xyz)
    assert a.fixes.has_z == b.fixes.has_z


def test_rows_and_blocks_give_the_same_batch_and_tracker_input() -> None:
    rows, blocks = _parse_msgpack(_batch(blocks=False)), _parse_msgpack(_batch(blocks=True))
    assert rows == blocks
    assert np.isnan(blocks.ranges.sigma_m[1]) and blocks.ranges.sigma_m[0] == 0.3
    meta = SessionMeta()
    _same_chunk(to_chunk(rows, meta, {}), to_chunk(blocks, meta, {}))
    assert rows.time_span() == blocks.time_span() == (10.0, 10.04)
    assert rows.n_samples() == 5 + 1 + 2 + 1 + 2 + 1


def test_json_rows_equal_msgpack_blocks() -> None:
    import json

    body = json.dumps(_batch(blocks=False)).encode()
    assert parse_batch(decode_body(body, "application/json")) == \
        _parse_msgpack(_batch(blocks=True))


def test_float32_blocks_are_widened_and_times_must_be_float64() -> None:
    imu = _imu(4)
    value = {"seq": 0, "imu": {"t": block(imu["t"]), "acc": block(imu["acc"], dtype="<f4")}}
    b = _parse_msgpack(value)
    assert b.imu is not None and b.imu.acc.dtype == np.float64
    np.testing.assert_array_equal(b.imu.acc, imu["acc"].astype(np.float32))
    value["imu"]["t"] = block(imu["t"], dtype="<f4")
    with pytest.raises(BatchError, match=r"imu\.t\.dtype '<f4': one of <f8"):
        _parse_msgpack(value)


def _with(part: str, field: str, column: Any) -> dict[str, Any]:
    value = _batch(blocks=True)
    value[part] = {**value[part], field: column}
    return value


_ACC = _imu(5)["acc"]
_T = _imu(5)["t"]


@pytest.mark.parametrize(("value", "message"), [
    (_with("imu", "acc", {**block(_ACC), "dtype": "<i4"}), r"imu\.acc\.dtype '<i4'"),
    (_with("imu", "acc", {**block(_ACC), "dtype": ">f8"}), r"imu\.acc\.dtype '>f8'"),
    (_with("imu", "acc", {**block(_ACC), "shape": [5, 2]}), r"imu\.acc\.shape \[5, 2\]"),
    (_with("imu", "acc", {**block(_ACC), "shape": [15]}), r"imu\.acc\.shape \[15\]"),
    (_with("imu", "acc", {**block(_ACC), "shape": [4, 3]}), r"imu\.acc\.data has 120 bytes"),
    (_with("imu", "acc", {**block(_ACC), "shape": [-5, 3]}), r"imu\.acc\.shape"),
    (_with("imu", "acc", {**block(_ACC), "shape": [True, 3]}), r"imu\.acc\.shape"),
    (_with("imu", "acc", {**block(_ACC), "data": "abc"}), r"imu\.acc\.data: expected bytes"),
    (_with("imu", "acc", {**block(_ACC), "order": "C"}), r"imu\.acc: a column block has"),
    (_with("imu", "acc", {"dtype": "<f8", "data": b""}), r"imu\.acc: a column block has"),
    (_with("imu", "acc", block(np.where(np.eye(5, 3) > 0, np.nan, _ACC))),
     r"imu\.acc\[0\] is not a finite number"),
    (_with("imu", "gyr", block(np.where(np.arange(15).reshape(5, 3) == 7, np.inf, _ACC))),
     r"imu\.gyr\[2\] is not a finite number"),
    (_with("imu", "t", block(_T[::-1].copy())), r"imu\.t\[1\] .* increase strictly"),
    (_with("imu", "t", block(np.repeat(_T[:1], 5))), r"imu\.t\[1\] .* increase strictly"),
    (_with("imu", "t", [10.0, 10.01, float("nan"), 10.03, 10.04]),
     r"imu\.t\[2\] is not a finite number"),
    (_with("imu", "acc", block(_ACC[:4])), r"imu\.acc has 4 rows, imu\.t has 5"),
    (_with("imu", "acc", [[1, 2, 3]] * 4 + [[1, 2]]), r"imu\.acc: rows of different lengths"),
    (_with("imu", "acc", [["1", "2", "3"]] * 5), r"imu\.acc: expected n x 3 numbers"),
    (_with("imu", "acc", 5), r"imu\.acc: expected a list or a column block"),
    (_with("imu", "quat", block(_ACC)), r"imu: unknown field\(s\) 'quat'"),
    (_with("imu", "t", {"dtype": "<f8", "shape": [MAX_SAMPLES + 1],
                        "data": bytes(8 * (MAX_SAMPLES + 1))}), r"at most 2000 per part"),
    (_with("imu", "t", block(np.zeros(0))), r"imu\.t: at least 1 sample"),
    (_with("rss", "t", block(np.array([10.0, 9.0]))), r"rss\.t\[1\] .* must not decrease"),
    (_with("rss", "anchor", ["B1", 2]), r"rss\.anchor: expected a list of strings"),
    (_with("rss", "anchor", ["B1", ""]), r"rss\.anchor: identifiers have 1 to 200"),
    (_with("ranges", "sigma_m", block(np.array([0.3, np.inf]))),
     r"ranges\.sigma_m\[1\] is not a finite number"),
    (_with("baro", "p_pa", block(np.array([1013.0]))), r"hPa must be x 100"),
    (_with("fixes", "sigma_m", block(np.array([0.0]))), r"fixes\.sigma_m must be > 0"),
    (_with("fixes", "x", None), r"fixes\.x: field required"),
    ({**_batch(blocks=True), "extra": 1}, r"unknown field\(s\) 'extra'"),
    ({**_batch(blocks=True), "seq": True}, r"seq = True: an integer"),
    ({**_batch(blocks=True), "seq": 1.0}, r"seq = 1\.0: an integer"),
    ({**_batch(blocks=True), "seq": 2**31}, r"seq = 2147483648"),
    ({**_batch(blocks=True), "sos": 1}, r"sos = 1: true or false"),
    ({"seq": 0, "status": {"battery": 1.5}}, r"status\.battery = 1\.5"),
    ({"seq": 0, "status": {"battery": 0.5, "temp": 3}}, r"status: expected an object"),
    ({"seq": 0, "imu": [1, 2]}, r"imu: expected an object"),
    ({"seq": 0}, r"at least one of"),
])
def test_every_refusal_names_the_field(value: dict[str, Any], message: str) -> None:
    with pytest.raises(BatchError, match=message) as err:
        _parse_msgpack(value)
    assert err.value.status == 422


def test_nan_in_ranges_sigma_means_unknown_in_rows_and_blocks() -> None:
    b = _parse_msgpack(_with("ranges", "sigma_m", [float("nan"), 0.2]))
    assert b.ranges is not None and np.isnan(b.ranges.sigma_m[0])
    b = _parse_msgpack(_with("ranges", "sigma_m", None))
    assert b.ranges is not None and np.isnan(b.ranges.sigma_m).all()


finite = st.floats(-1e6, 1e6, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(acc=hnp.arrays(np.float64, st.tuples(st.integers(1, 40), st.just(3)), elements=finite),
       steps=st.lists(st.floats(1e-4, 1.0), min_size=40, max_size=40),
       t0=st.floats(-1e4, 1e5))
def test_blocks_rows_and_pickles_agree(acc: np.ndarray, steps: list[float], t0: float) -> None:
    """Any finite IMU with increasing times: rows, blocks and a pickled batch are one batch."""
    t = t0 + np.cumsum(steps[:len(acc)])
    if not (np.diff(t) > 0).all():
        return
    rows = _parse_msgpack({"seq": 1, "imu": {"t": t.tolist(), "acc": acc.tolist()}})
    blocks = _parse_msgpack({"seq": 1, "imu": {"t": block(t), "acc": block(acc)}})
    assert rows == blocks
    again = pickle.loads(pickle.dumps(blocks, protocol=pickle.HIGHEST_PROTOCOL))
    assert again == blocks and again.time_span() == (t[0], t[-1])
    assert blocks.imu is not None
    np.testing.assert_array_equal(blocks.imu.acc, acc)


def test_service_stores_blocks_as_received_and_refuses_bad_ones(
        live: Live, commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    a = new_agent(commander, mid)
    ctype = {"Content-Type": "application/msgpack"}
    good = msgpack.packb(_batch(blocks=True))
    bad = msgpack.packb(_with("imu", "acc", {**block(_ACC), "shape": [5, 2]}))
    with live.client(a["token"]) as agent:
        r = agent.post(f"{API}/ingest", content=good, headers=ctype)
        assert r.status_code == 200 and r.json()["status"] == "accepted", r.text
        r = agent.post(f"{API}/ingest", content=bad, headers=ctype)
        assert r.status_code == 422 and "imu.acc.shape [5, 2]" in r.json()["detail"]
    host = live.server.config.app.state.services.host
    from hrtls.service.host import decode_batch
    from hrtls.service.models import RawBatch

    with host.sessions() as db:
        row = db.query(RawBatch).filter(RawBatch.agent_id == a["agent"]["id"]).one()
    assert row.body == good
    assert decode_batch(row.body, row.content_type) == _parse_msgpack(_batch(blocks=False))
