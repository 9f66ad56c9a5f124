"""A radio survey file: RSS readings at known positions (``[prediction.radio_map] survey``).

A CSV table with the header :data:`hrtls.fusion.radio_map.SURVEY_COLUMNS` (``x_m, y_m`` in
the session's local frame, m; ``anchor``: the beacon's landmark id; ``rss_dbm``), one reading
a row, read by :func:`hrtls.io.csvtable.read_table` (errors name the line, column and value).
"""

from __future__ import annotations

from pathlib import Path

from hrtls.errors import InputError
from hrtls.fusion.radio_map import SURVEY_COLUMNS, RadioSurvey
from hrtls.io.csvtable import ColumnKind, read_table

KINDS: dict[str, ColumnKind] = {"x_m": "float", "y_m": "float", "anchor": "str",
                                "rss_dbm": "float"}
assert tuple(KINDS) == SURVEY_COLUMNS


def read_survey(path: str | Path) -> RadioSurvey:
    """The survey CSV file at ``path``."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read it ({exc.strerror})", where=str(p),
                         expected="a survey CSV file") from None
    table = read_table(data, name=str(p), kinds=KINDS, required=SURVEY_COLUMNS)
    if table.n_rows == 0:
        raise InputError("no readings", where=str(p),
                         expected=f"a header {','.join(SURVEY_COLUMNS)} and one reading a row")
    return RadioSurvey(table.float("x_m"), table.float("y_m"), table.str("anchor"),
                       table.float("rss_dbm"), source=str(p))
