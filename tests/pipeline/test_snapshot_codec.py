"""The snapshot codec: every value kind round-trips; the state it holds stays bounded."""

from __future__ import annotations

import math
import zlib
from collections import deque

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hrtls.errors import FormatError
from hrtls.fusion.state import FilterState
from hrtls.gait.motion_detector import RunningStd, RunningStdState
from hrtls.pipeline import snapshot as snap
from hrtls.pipeline.baro_stage import BaroStage

_scalars = st.none() | st.booleans() | st.integers(-2**62, 2**62) | st.floats() | st.text(
    max_size=8) | st.binary(max_size=8)
_arrays = hnp.arrays(st.sampled_from([np.float64, np.int64, np.uint8, np.bool_]),
                     hnp.array_shapes(min_dims=0, max_dims=3, max_side=4))
_keys = st.text(max_size=6) | st.integers(-5, 5)


def _values(leaves: st.SearchStrategy) -> st.SearchStrategy:
    return st.recursive(leaves, lambda inner: (
        st.lists(inner, max_size=4) | st.tuples(inner, inner)
        | st.dictionaries(_keys, inner, max_size=4)
        | st.lists(inner, max_size=4).map(lambda v: deque(v, maxlen=7))), max_leaves=12)


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray):
        return (isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape
                and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)  # type: ignore[index]
    if isinstance(a, list | tuple | deque):
        return (len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))  # type: ignore[arg-type]
                and getattr(a, "maxlen", None) == getattr(b, "maxlen", None))
    return a == b


@settings(max_examples=200, deadline=None)
@given(_values(_scalars | _arrays))
def test_every_value_kind_round_trips(value: object) -> None:
    state = {"v": value}
    assert _same(snap.unpack(snap.pack(state)), state)


def test_state_dataclasses_and_numpy_scalars_round_trip() -> None:
    fs = FilterState(t=1.5, x=np.arange(4.0), P=np.eye(4))
    out = snap.unpack(snap.pack({"f": fs, "n": np.float64(2.5), "i": np.int64(3)}))
    assert isinstance(out["f"], FilterState) and out["f"].t == 1.5
    np.testing.assert_array_equal(out["f"].P, np.eye(4))
    assert out["n"] == 2.5 and type(out["n"]) is float and out["i"] == 3


def test_refuses_unknown_classes_and_extensions() -> None:
    class Other:
        pass

    with pytest.raises(TypeError, match="cannot snapshot"):
        snap.pack({"x": Other()})
    body = msgpack.packb({"x": msgpack.ExtType(5, msgpack.packb(["os.system", {}]))})
    with pytest.raises(FormatError, match="unknown state class"):
        snap.unpack(_framed(body))
    body = msgpack.packb({"x": msgpack.ExtType(42, b"")})
    with pytest.raises(FormatError, match="extension type 42"):
        snap.unpack(_framed(body))
    with pytest.raises(FormatError, match="corrupt snapshot"):
        snap.unpack(_framed(body)[:-3])                                  # body cut off
    with pytest.raises(FormatError, match="corrupt snapshot"):
        snap.unpack(snap.MAGIC + bytes([snap.VERSION]) + b"\x01")       # no length


def _framed(body: bytes) -> bytes:
    """A version-4 snapshot around a hand-made msgpack body."""
    import struct

    import pyarrow as pa

    return (snap.MAGIC + bytes([4]) + struct.pack("<I", len(body))
            + pa.compress(body, codec="zstd", asbytes=True))


def test_reads_version_3_snapshots() -> None:
    """Version 3 (zlib) snapshots, as the service stored them before, are still read."""
    state = {"a": np.arange(4.0), "b": (1, "x")}
    body = snap._packb(state)
    out = snap.unpack(snap.MAGIC + bytes([3]) + zlib.compress(body, 1))
    np.testing.assert_array_equal(out["a"], state["a"])
    assert out["b"] == (1, "x")


def test_reads_version_2_snapshots() -> None:
    arr = np.arange(6.0).reshape(2, 3)
    v2 = {"~d": [["a", {"~nd": "<f8", "s": [2, 3], "d": arr.tobytes()}],
                 [1, {"~t": [1, "x"]}], ["q", {"~q": [1, 2], "m": 3}]]}
    out = snap.unpack(snap.MAGIC + bytes([2]) + zlib.compress(msgpack.packb(v2)))
    np.testing.assert_array_equal(out["a"], arr)
    assert out[1] == (1, "x") and out["q"] == deque([1, 2], maxlen=3)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.001, 0.3), min_size=1, max_size=300), st.integers(0, 299))
def test_running_std_state_keeps_only_its_window(dts: list[float], cut: int) -> None:
    """The compact state (window samples only) continues exactly like the whole ring."""
    t = np.cumsum(dts)
    x = np.sin(t * 7.0) + t
    cut = min(cut, len(t))
    whole = RunningStd(window_s=2.0, max_rate_hz=50.0)
    m_ref, s_ref = whole.update(t, x)
    first = RunningStd(window_s=2.0, max_rate_hz=50.0)
    m1, s1 = first.update(t[:cut], x[:cut])
    d = first.state.to_dict()
    assert len(d["t"]) == int(first.state.ints[1])
    second = RunningStd(window_s=2.0, max_rate_hz=50.0)
    second.state = RunningStdState.from_dict(d)
    m2, s2 = second.update(t[cut:], x[cut:])
    np.testing.assert_array_equal(np.concatenate([m1, m2]), m_ref)
    np.testing.assert_array_equal(np.concatenate([s1, s2]), s_ref)


def test_baro_stage_without_pressure_keeps_few_step_ends() -> None:
    """Steps arrive all mission long; without pressure they must not pile up in the state."""
    stage = BaroStage(floor_height_m=3.0, t_pose=0.0, z_pose_m=0.0)
    for k in range(2000):
        stage.add_steps(np.array([k * 0.5 + 0.1, k * 0.5 + 0.35]))
        stage.advance(k * 0.5)
    assert len(stage.state()["step_ends"]) <= 12
