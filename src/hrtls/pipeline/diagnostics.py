"""The tracker's record of every correction attempt, cheap to fill at tens of kHz.

Corrections done in the compiled event loop (tight RSS readings, ranges) are stored as column
blocks and turned into :class:`~hrtls.fusion.gating.UpdateDiagnostics` only when somebody reads
them; :meth:`DiagnosticsLog.counts` and :meth:`DiagnosticsLog.first_rejected` work on the
columns directly. The log is a read-only sequence of ``UpdateDiagnostics`` in event order.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from itertools import chain
from typing import Any, overload

import numpy as np

from hrtls.fusion.gating import Status, UpdateDiagnostics

ACCEPTED, GATE, NEAR, NOT_SPD, SKIPPED = 0, 1, 2, 3, 4
"""Outcome codes of a block row (the kernel's codes)."""
REJECTED_REASON, ACCEPTED_REASON = 6, 7
"""Rows rejected / accepted without an innovation (e.g. collinear anchors, a WLS jump); the
text is the row's ``reason``."""


@dataclass(frozen=True, slots=True, eq=False)
class DiagnosticsBlock:
    """Scalar corrections of one kernel run, as columns.

    Attributes
    ----------
    kind: ``"rss"`` or ``"range"`` per row. t: times, s. code: outcome code per row.
    nis, s, nu: NIS, innovation variance and innovation (NaN when not formed).
    source: anchor / node id per row. reason: text of skipped rows and of the ``*_REASON``
    codes (else ``""``).
    threshold: chi-square gate used.
    dof: measurement dimension per row (None: 1 for every row). Rows with ``dof == 2`` take
    their innovation and ``S`` from ``nu2`` (n, 2) and ``s2`` (n, 3: ``S00, S01, S11``) and
    are gated by ``threshold2``.
    """

    kind: Sequence[str]
    t: np.ndarray
    code: np.ndarray
    nis: np.ndarray
    s: np.ndarray
    nu: np.ndarray
    source: Sequence[str]
    reason: Sequence[str]
    threshold: float
    dof: np.ndarray | None = None
    nu2: np.ndarray | None = None
    s2: np.ndarray | None = None
    threshold2: float = float("inf")

    def row(self, i: int) -> UpdateDiagnostics:
        """Row ``i`` as :class:`UpdateDiagnostics`."""
        code = int(self.code[i])
        kind, t, src = str(self.kind[i]), float(self.t[i]), str(self.source[i])
        dof = 1 if self.dof is None else int(self.dof[i])
        if code == SKIPPED:
            return UpdateDiagnostics(kind, t, "skipped", source=src, reason=str(self.reason[i]))
        if code == REJECTED_REASON:
            return UpdateDiagnostics(kind, t, "rejected", source=src, reason=str(self.reason[i]))
        if code == ACCEPTED_REASON:
            return UpdateDiagnostics(kind, t, "accepted", dof=dof, source=src,
                                     reason=str(self.reason[i]))
        if code == NEAR:
            what = "anchor" if kind == "rss" else "node"
            return UpdateDiagnostics(kind, t, "rejected", source=src,
                                     reason=f"estimate on top of the {what}")
        status: Status = "accepted" if code == ACCEPTED else "rejected"
        reason = "" if code == ACCEPTED else ("failed the chi-square gate" if code == GATE
                                              else "innovation covariance not positive definite")
        if dof == 2 and self.nu2 is not None and self.s2 is not None:
            s00, s01, s11 = (float(v) for v in self.s2[i])
            return UpdateDiagnostics(kind, t, status, nis=float(self.nis[i]), dof=2,
                                     threshold=self.threshold2,
                                     innovation=np.array(self.nu2[i], dtype=np.float64),
                                     innovation_cov=np.array([[s00, s01], [s01, s11]]),
                                     source=src, reason=reason)
        return UpdateDiagnostics(kind, t, status, nis=float(self.nis[i]), dof=1,
                                 threshold=self.threshold, innovation=np.array([self.nu[i]]),
                                 innovation_cov=np.array([[self.s[i]]]), source=src,
                                 reason=reason)

    def status_names(self) -> list[str]:
        """Status of each row."""
        names = ("accepted", "rejected", "skipped")
        return [names[i] for i in _status_index(self.code).tolist()]


class DiagnosticsLog(Sequence[UpdateDiagnostics]):
    """Every correction attempt in event order (blocks materialized on first read)."""

    def __init__(self) -> None:
        self._parts: list[UpdateDiagnostics | DiagnosticsBlock] = []
        self._flat: list[UpdateDiagnostics] | None = None
        self._n = 0
        self._accepted_t = np.zeros(0)
        self._accepted_parts = 0
        self._counts: dict[str, dict[str, int]] = {}
        self._counted_parts = 0
        self._rejected: list[UpdateDiagnostics] = []
        self._rejected_dicts: list[dict[str, Any]] = []
        self._rejected_parts = 0
        self._rejected_cut = False

    def accepted_times(self) -> np.ndarray:
        """Times of the accepted records, in order (kept up to date incrementally)."""
        new: list[np.ndarray] = [self._accepted_t]
        for p in self._parts[self._accepted_parts:]:
            if isinstance(p, DiagnosticsBlock):
                new.append(p.t[(p.code == ACCEPTED) | (p.code == ACCEPTED_REASON)])
            elif p.accepted:
                new.append(np.array([p.t]))
        self._accepted_parts = len(self._parts)
        if len(new) > 1:
            self._accepted_t = np.concatenate(new)
        return self._accepted_t

    def append(self, item: UpdateDiagnostics) -> None:
        """Add one record."""
        self._parts.append(item)
        self._n += 1
        self._flat = None

    def extend(self, items: Sequence[UpdateDiagnostics]) -> None:
        """Add several records."""
        for d in items:
            self.append(d)

    def add_block(self, block: DiagnosticsBlock) -> None:
        """Add the rows of a kernel run."""
        if len(block.t):
            self._parts.append(block)
            self._n += len(block.t)
            self._flat = None

    def _materialize(self) -> list[UpdateDiagnostics]:
        if self._flat is None:
            out: list[UpdateDiagnostics] = []
            for p in self._parts:
                if isinstance(p, DiagnosticsBlock):
                    out.extend(p.row(i) for i in range(len(p.t)))
                else:
                    out.append(p)
            self._flat = out
        return self._flat

    def __len__(self) -> int:
        return self._n

    @overload
    def __getitem__(self, index: int) -> UpdateDiagnostics: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[UpdateDiagnostics]: ...

    def __getitem__(self, index: int | slice) -> UpdateDiagnostics | Sequence[UpdateDiagnostics]:
        return self._materialize()[index]

    def __iter__(self) -> Iterator[UpdateDiagnostics]:
        return iter(self._materialize())

    def counts(self) -> dict[str, dict[str, int]]:
        """Counts per kind and status (as :func:`hrtls.fusion.gating.summarize`).

        Kept up to date incrementally: only the records added since the last call are read.
        """
        out = self._counts
        new = self._parts[self._counted_parts:]
        self._counted_parts = len(self._parts)
        blocks = [p for p in new if isinstance(p, DiagnosticsBlock)]
        for p in new:
            if not isinstance(p, DiagnosticsBlock):
                d = out.setdefault(p.kind, {})
                d[p.status] = d.get(p.status, 0) + 1
        if blocks:
            kinds = np.array(list(chain.from_iterable(b.kind for b in blocks)), dtype=object)
            code = np.concatenate([b.code for b in blocks])
            status = _status_index(code)
            names = ("accepted", "rejected", "skipped")
            for k in sorted(set(kinds.tolist())):
                table = np.bincount(status[kinds == k], minlength=3)
                d = out.setdefault(str(k), {})
                for j in range(3):
                    if table[j]:
                        d[names[j]] = d.get(names[j], 0) + int(table[j])
        return {k: dict(v) for k, v in out.items()}

    def first_rejected(self, limit: int) -> list[UpdateDiagnostics]:
        """The first ``limit`` rejected records, in order.

        The log only grows, so the records found are kept and only later records are read.
        """
        if limit > len(self._rejected) and self._rejected_cut:
            self._rejected, self._rejected_dicts = [], []
            self._rejected_parts, self._rejected_cut = 0, False
        out = self._rejected
        new = self._parts[self._rejected_parts:]
        if len(out) < limit and new:
            self._rejected_parts = len(self._parts)
            blocks = [p for p in new if isinstance(p, DiagnosticsBlock)]
            if blocks:
                # rejected rows of every block at once, then per block only where there are some
                bad = _status_index(np.concatenate([b.code for b in blocks])) == 1
                sizes = [len(b.code) for b in blocks]
                offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
                cs = np.concatenate([[0], np.cumsum(bad)])
                n_bad = cs[offsets[1:]] - cs[offsets[:-1]]
            i_block = 0
            for p in new:
                if len(out) >= limit:
                    self._rejected_cut = True
                    break
                if isinstance(p, DiagnosticsBlock):
                    if n_bad[i_block]:
                        o = int(offsets[i_block])
                        idx = np.flatnonzero(bad[o:o + len(p.code)])
                        self._rejected_cut |= len(idx) > limit - len(out)
                        out.extend(p.row(int(i)) for i in idx[: limit - len(out)])
                    i_block += 1
                elif p.status == "rejected":
                    out.append(p)
        return out[:limit]

    def first_rejected_dicts(self, limit: int) -> list[dict[str, Any]]:
        """:meth:`first_rejected` as ``to_dict`` forms (converted once per record)."""
        rows = self.first_rejected(limit)
        done = self._rejected_dicts
        done.extend(d.to_dict() for d in rows[len(done):])
        return done[:limit]


def _status_index(code: np.ndarray) -> np.ndarray:
    """0 accepted, 1 rejected, 2 skipped for block outcome codes."""
    acc = (code == ACCEPTED) | (code == ACCEPTED_REASON)
    return np.where(acc, 0, np.where(code == SKIPPED, 2, 1))
