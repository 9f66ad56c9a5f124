import numpy as np
import pytest

from hrtls.errors import FormatError, InputError
from hrtls.io.intervals import read_intervals


def test_reads_intervals_with_their_lines(tmp_path):
    p = tmp_path / "positions.csv"
    p.write_text("t_start,t_end,position\n0,2,+x\n\n2.5,4,-z\n")
    iv = read_intervals(p, columns={"position": "str"})
    assert np.array_equal(iv.t_start, [0.0, 2.5]) and np.array_equal(iv.t_end, [2.0, 4.0])
    assert list(iv.table.str("position")) == ["+x", "-z"]
    assert list(iv.line) == [2, 4]


def test_backward_interval_names_its_line(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("t_start,t_end,activity\n0,1,walking\n\n5,4,standing\n")
    with pytest.raises(FormatError, match=r"line 4.*t_start < t_end"):
        read_intervals(p, columns={"activity": "str"})


def test_bad_number_and_header(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("t_start,t_end,axis,rate_rad_s\n0,1,x,fast\n")
    with pytest.raises(FormatError, match=r"line 2: 'rate_rad_s' is 'fast'"):
        read_intervals(p, columns={"axis": "str", "rate_rad_s": "float"})
    p.write_text("start,end\n")
    with pytest.raises(FormatError, match="line 1"):
        read_intervals(p, columns={"axis": "str"})
    with pytest.raises(InputError, match="cannot be read"):
        read_intervals(tmp_path / "missing.csv", columns={})
