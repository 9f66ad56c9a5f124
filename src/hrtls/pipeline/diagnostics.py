"""The tracker's record of every correction attempt, cheap to fill at tens of kHz.

Corrections done in the compiled event loop (tight RSS readings, ranges) are stored as column
blocks and turned into :class:`~hrtls.fusion.gating.UpdateDiagnostics` only when somebody reads
them; :meth:`DiagnosticsLog.counts` and :meth:`DiagnosticsLog.first_rejected` work on the
columns directly. The log is a read-only sequence of ``UpdateDiagnostics`` in event order.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import overload

import numpy as np

from hrtls.fusion.gating import Status, UpdateDiagnostics

ACCEPTED, GATE, NEAR, NOT_SPD, SKIPPED = 0, 1, 2, 3, 4
"""Outcome codes of a block row (the kernel's codes)."""


@dataclass(frozen=True, slots=True, eq=False)
class DiagnosticsBlock:
    """Scalar corrections of one kernel run, as columns.

    Attributes
    ----------
    kind: ``"rss"`` or ``"range"`` per row. t: times, s. code: outcome code per row.
    nis, s, nu: NIS, innovation variance and innovation (NaN when not formed).
    source: anchor / node id per row. reason: text of skipped rows (else ``""``).
    threshold: chi-square gate used.
    """

    kind: list[str]
    t: np.ndarray
    code: np.ndarray
    nis: np.ndarray
    s: np.ndarray
    nu: np.ndarray
    source: list[str]
    reason: list[str]
    threshold: float

    def row(self, i: int) -> UpdateDiagnostics:
        """Row ``i`` as :class:`UpdateDiagnostics`."""
        code = int(self.code[i])
        kind, t, src = self.kind[i], float(self.t[i]), self.source[i]
        if code == SKIPPED:
            return UpdateDiagnostics(kind, t, "skipped", source=src, reason=self.reason[i])
        if code == NEAR:
            what = "anchor" if kind == "rss" else "node"
            return UpdateDiagnostics(kind, t, "rejected", source=src,
                                     reason=f"estimate on top of the {what}")
        status: Status = "accepted" if code == ACCEPTED else "rejected"
        reason = "" if code == ACCEPTED else ("failed the chi-square gate" if code == GATE
                                              else "innovation covariance not positive definite")
        return UpdateDiagnostics(kind, t, status, nis=float(self.nis[i]), dof=1,
                                 threshold=self.threshold, innovation=np.array([self.nu[i]]),
                                 innovation_cov=np.array([[self.s[i]]]), source=src,
                                 reason=reason)

    def status_names(self) -> list[str]:
        """Status of each row."""
        return ["accepted" if c == ACCEPTED else ("skipped" if c == SKIPPED else "rejected")
                for c in self.code.tolist()]


class DiagnosticsLog(Sequence[UpdateDiagnostics]):
    """Every correction attempt in event order (blocks materialized on first read)."""

    def __init__(self) -> None:
        self._parts: list[UpdateDiagnostics | DiagnosticsBlock] = []
        self._flat: list[UpdateDiagnostics] | None = None
        self._n = 0

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
        """Counts per kind and status (as :func:`hrtls.fusion.gating.summarize`)."""
        out: dict[str, dict[str, int]] = {}
        blocks = [p for p in self._parts if isinstance(p, DiagnosticsBlock)]
        for p in self._parts:
            if not isinstance(p, DiagnosticsBlock):
                d = out.setdefault(p.kind, {})
                d[p.status] = d.get(p.status, 0) + 1
        if blocks:
            kinds = np.concatenate([np.asarray(b.kind) for b in blocks])
            code = np.concatenate([b.code for b in blocks])
            status = np.where(code == ACCEPTED, 0, np.where(code == SKIPPED, 2, 1))
            names = ("accepted", "rejected", "skipped")
            uk, ik = np.unique(kinds, return_inverse=True)
            table = np.zeros((len(uk), 3), dtype=np.int64)
            np.add.at(table, (ik, status), 1)
            for i, k in enumerate(uk.tolist()):
                d = out.setdefault(k, {})
                for j in range(3):
                    if table[i, j]:
                        d[names[j]] = d.get(names[j], 0) + int(table[i, j])
        return out

    def first_rejected(self, limit: int) -> list[UpdateDiagnostics]:
        """The first ``limit`` rejected records, in order."""
        out: list[UpdateDiagnostics] = []
        for p in self._parts:
            if len(out) >= limit:
                break
            if isinstance(p, DiagnosticsBlock):
                idx = np.flatnonzero((p.code != ACCEPTED) & (p.code != SKIPPED))
                out.extend(p.row(int(i)) for i in idx[: limit - len(out)])
            elif p.status == "rejected":
                out.append(p)
        return out
