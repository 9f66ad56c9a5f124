"""The mission folder: every agent's session plus the dropped network (docs/architecture.md).

``MISSION_DIR/``

* ``mission.json``: ``{"format": "hrtls-mission", "version": 1, "name": ..., "agents":
  [{"name", "kind" (rescuer | robot), "session" (session folder or zip, relative)}]}``;
* ``network.json`` (optional): ``{"nodes": [{"id": ...}]}``, the dropped range nodes, ids only
  (an export of the service adds each node's live estimate under ``"service"``);
* ``landmarks.json`` (optional): the mission's known location messages (session format), given
  to every agent (an agent's own landmark of the same id wins);
* ``landmark_updates.json`` (optional): new versions of location messages during the mission
  (moved, ``"status": "destroyed"``, a ``hazard`` nearby), each with its time ``updated`` (s);
  every agent uses each version from that time on (:mod:`hrtls.pipeline.landmark_updates`);
* one session per agent (:func:`hrtls.io.session.read_session`; other recordings are converted
  first, ``hrtls convert``);
* ``network_ranges.csv`` (optional): ``t_s,node_a,node_b,range_m``, ranges measured between
  two dropped nodes at mission time ``t_s`` (the agents' session clock), m
  (:class:`hrtls.mission.network_ranges.NetworkRanges`);
* ``network_truth.json`` (optional, scoring only): ``{"nodes": [{"id", "position": [x, y(, z)]}]}``.

Ground truth (agents' ``truth.csv`` / ``checkpoints.csv``, ``network_truth.json``) is read into
:class:`MissionFolder` apart from the sessions the estimator gets (:meth:`MissionFolder.sessions`).
"""

from __future__ import annotations

import json
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from hrtls.data import Session
from hrtls.data.clocks import check_session_clocks
from hrtls.data.landmarks import Landmark
from hrtls.errors import DegradedInputWarning, FormatError, InputError
from hrtls.io.csvtable import ColumnKind, arrow_from_columns, csv_bytes, read_table
from hrtls.io.session import (
    is_session,
    landmark_list,
    landmarks_from_json,
    pydantic_problem,
    read_session,
)
from hrtls.mission.network_ranges import NetworkRanges

FloatArray = NDArray[np.float64]

MISSION_FORMAT: Literal["hrtls-mission"] = "hrtls-mission"
MISSION_VERSION = 1
"""Version of ``mission.json`` this module reads and writes."""
MISSION_FILE = "mission.json"
NETWORK_FILE = "network.json"
LANDMARKS_FILE = "landmarks.json"
LANDMARK_UPDATES_FILE = "landmark_updates.json"
NETWORK_TRUTH_FILE = "network_truth.json"
NETWORK_RANGES_FILE = "network_ranges.csv"
_NETWORK_RANGES_COLUMNS: dict[str, ColumnKind] = {
    "t_s": "float", "node_a": "str", "node_b": "str", "range_m": "float"}
AgentKind = Literal["rescuer", "robot"]


def is_folder_name(name: str) -> bool:
    """True when ``name`` can name an agent's result folder (``OUT/agents/<name>``)."""
    return bool(name) and name == name.strip() and name not in (".", "..") \
        and "/" not in name and "\\" not in name


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class AgentEntry(_Strict):
    """One agent of ``mission.json``."""

    name: str = Field(min_length=1)
    kind: AgentKind
    session: str = Field(min_length=1, description="folder or zip, relative to the mission")

    @field_validator("name")
    @classmethod
    def _folder_name(cls, value: str) -> str:
        if not is_folder_name(value):
            raise ValueError("must be usable as a folder name (no '/', '\\', '.', '..', "
                             "no surrounding spaces)")
        return value

    @field_validator("session")
    @classmethod
    def _inside(cls, value: str) -> str:
        p = PurePosixPath(value.replace("\\", "/"))
        if p.is_absolute() or ".." in p.parts or re.match(r"^[A-Za-z]:", value):
            raise ValueError("must be a relative path inside the mission folder")
        return value


class MissionFileModel(_Strict):
    """``mission.json``."""

    format: Literal["hrtls-mission"]
    version: int
    name: str = ""
    agents: list[AgentEntry]
    notes: list[str] = Field(default_factory=list)
    source: dict[str, Any] = Field(default_factory=dict)
    service: dict[str, Any] = Field(default_factory=dict, description="what the supervisor "
                                    "knew, when exported from it (``hrtls mission export``)")


class NodeEntry(_Strict):
    """A dropped node of ``network.json``: an id, no position.

    ``service``: what a live service's mission estimator had estimated (``hrtls mission
    export``); not an input of the tracker.
    """

    id: str = Field(min_length=1)
    service: dict[str, Any] | None = None


class NetworkModel(_Strict):
    """``network.json``."""

    nodes: list[NodeEntry]


class NodeTruthEntry(_Strict):
    """A node of ``network_truth.json``."""

    id: str = Field(min_length=1)
    position: tuple[float, float] | tuple[float, float, float]


class NetworkTruthModel(_Strict):
    """``network_truth.json``."""

    nodes: list[NodeTruthEntry]


@dataclass(frozen=True, eq=False)
class MissionAgent:
    """An agent of a mission: its entry and its whole session (ground truth included)."""

    name: str
    kind: AgentKind
    path: Path
    session: Session


@dataclass(frozen=True, eq=False)
class MissionFolder:
    """A read mission folder.

    Attributes
    ----------
    path:
        The folder.
    name:
        Mission name.
    agents:
        Agents by name, in the order of ``mission.json``.
    nodes:
        Ids of the dropped nodes (``network.json``).
    landmarks:
        The mission's known location messages (``landmarks.json``).
    node_truth_m:
        ``id -> (2,) or (3,)`` true node positions, m (``network_truth.json``; None without).
    landmark_updates:
        Versions of location messages during the mission, by time (``landmark_updates.json``).
    network_ranges:
        Ranges between dropped nodes (``network_ranges.csv``; none without it).
    """

    path: Path
    name: str
    agents: dict[str, MissionAgent]
    nodes: tuple[str, ...]
    landmarks: dict[str, Landmark]
    node_truth_m: dict[str, FloatArray] | None
    landmark_updates: tuple[Landmark, ...] = ()
    network_ranges: NetworkRanges = field(default_factory=NetworkRanges.empty)

    def sessions(self) -> dict[str, Session]:
        """What the estimator gets: each agent's session without its ground truth."""
        return {k: a.session.with_parts(truth=None, checkpoints=None)
                for k, a in self.agents.items()}


def _load_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8-sig"))
    except UnicodeDecodeError:
        raise FormatError("not UTF-8 text", where=str(path), expected="a UTF-8 JSON file"
                          ) from None
    except json.JSONDecodeError as exc:
        raise FormatError(exc.msg, where=f"{path} line {exc.lineno} column {exc.colno}",
                          expected="valid JSON") from None


def _model(cls: type[BaseModel], data: Any, *, where: Path, expected: str) -> Any:
    if not isinstance(data, dict):
        raise FormatError(f"top level is {type(data).__name__}", where=str(where),
                          expected="a JSON object")
    try:
        return cls.model_validate(data)
    except ValidationError as exc:
        raise FormatError(pydantic_problem(exc), where=str(where), expected=expected) from None


def _unique(values: Sequence[str], *, what: str, where: Path) -> None:
    seen: set[str] = set()
    for v in values:
        if v in seen:
            raise FormatError(f"duplicate {what} {v!r}", where=str(where),
                              expected=f"unique {what}s")
        seen.add(v)


def read_mission(path: Path | str, *, repair: bool = False) -> MissionFolder:
    """Read a mission folder (see the module doc); every problem names its file and field.

    ``repair``: let the session reader repair the agents' sessions (with warnings), as
    :func:`hrtls.io.session.read_session` does.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputError("no such folder", where=str(root),
                         expected=f"a mission folder holding {MISSION_FILE}")
    mfile = root / MISSION_FILE
    if not mfile.is_file():
        raise InputError(f"no {MISSION_FILE}", where=str(root),
                         expected="a mission folder (docs/architecture.md, 'The mission folder')")
    data = _load_json(mfile)
    # the version first: another version may have other fields
    if isinstance(data, dict) and "version" in data and data["version"] != MISSION_VERSION:
        raise FormatError(f"field 'version': {data['version']!r}", where=str(mfile),
                          expected=f"version {MISSION_VERSION} (this hrtls reads only it)")
    spec: MissionFileModel = _model(
        MissionFileModel, data, where=mfile,
        expected=f'{{"format": "{MISSION_FORMAT}", "version": {MISSION_VERSION}, "agents": '
                 '[{"name", "kind": rescuer | robot, "session"}]}')
    if not spec.agents:
        raise FormatError("field 'agents': no agents", where=str(mfile),
                          expected="at least one agent with a session")
    _unique([a.name for a in spec.agents], what="agent name", where=mfile)
    _unique([a.session for a in spec.agents], what="agent session", where=mfile)
    nodes: tuple[str, ...] = ()
    if (root / NETWORK_FILE).is_file():
        net: NetworkModel = _model(NetworkModel, _load_json(root / NETWORK_FILE),
                                   where=root / NETWORK_FILE,
                                   expected='{"nodes": [{"id": ...}]} (ids only: a node with a '
                                            'known position is a landmark, landmarks.json)')
        nodes = tuple(n.id for n in net.nodes)
        _unique(nodes, what="node id", where=root / NETWORK_FILE)
    landmarks: dict[str, Landmark] = {}
    if (root / LANDMARKS_FILE).is_file():
        landmarks = landmarks_from_json(_load_json(root / LANDMARKS_FILE),
                                        where=str(root / LANDMARKS_FILE))
    clash = sorted(set(nodes) & set(landmarks))
    if clash:
        raise FormatError(f"node(s) {', '.join(clash)} also in {LANDMARKS_FILE}",
                          where=str(root / NETWORK_FILE),
                          expected="a dropped node (no position) or a landmark, not both")
    agents = _read_agents(mfile, spec.agents, nodes, landmarks, repair=repair)
    truth = None
    if (root / NETWORK_TRUTH_FILE).is_file():
        nt: NetworkTruthModel = _model(NetworkTruthModel, _load_json(root / NETWORK_TRUTH_FILE),
                                       where=root / NETWORK_TRUTH_FILE,
                                       expected='{"nodes": [{"id", "position": [x, y(, z)]}]}')
        truth = {n.id: np.asarray(n.position, dtype=np.float64) for n in nt.nodes}
    return MissionFolder(root, spec.name, agents, nodes, landmarks, truth,
                         _read_landmark_updates(root / LANDMARK_UPDATES_FILE, nodes),
                         read_network_ranges(root / NETWORK_RANGES_FILE, nodes))


def read_network_ranges(path: Path, nodes: Sequence[str]) -> NetworkRanges:
    """``network_ranges.csv`` (none without the file); a bad row names its line and field.

    Ids not in ``network.json`` (``nodes``) are warned of, as an agent's unknown ids are.
    """
    if not path.is_file():
        return NetworkRanges.empty()
    cols = list(_NETWORK_RANGES_COLUMNS)
    tab = read_table(path.read_bytes(), name=str(path), kinds=_NETWORK_RANGES_COLUMNS,
                     required=cols)
    t, a, b, r = tab.float("t_s"), tab.str("node_a"), tab.str("node_b"), tab.float("range_m")
    for bad, fld, problem, expected in ((r <= 0, "range_m", "range", "a distance > 0 m"),
                                        (a == b, "node_b", "the same node as node_a",
                                         "two different nodes")):
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            value = r[i] if fld == "range_m" else repr(str(b[i]))
            raise FormatError(f"{problem} {value}", where=f"{path} line {i + 2} column {fld}",
                              expected=expected)
    out = NetworkRanges.concat([NetworkRanges(t, a, b, r)])
    left = sorted(set(out.nodes()) - set(nodes))
    if left:
        shown = ", ".join(left[:5]) + (" ..." if len(left) > 5 else "")
        warnings.warn(f"{path}: {len(left)} id(s) not in the mission's {NETWORK_FILE} ({shown})",
                      DegradedInputWarning, stacklevel=3)
    return out


def write_network_ranges(path: Path | str, ranges: NetworkRanges) -> Path:
    """Write ``network_ranges.csv`` (module doc) into the folder ``path``."""
    out = Path(path) / NETWORK_RANGES_FILE
    out.write_bytes(csv_bytes(arrow_from_columns({
        "t_s": ranges.t_s, "node_a": ranges.node_a, "node_b": ranges.node_b,
        "range_m": ranges.range_m})))
    return out


def _read_landmark_updates(path: Path, nodes: Sequence[str]) -> tuple[Landmark, ...]:
    """The versions of ``landmark_updates.json`` by time (none without the file)."""
    if not path.is_file():
        return ()
    out = landmark_list(_load_json(path), where=str(path))
    for i, lm in enumerate(out):
        if lm.updated is None:
            raise FormatError("no field 'updated'", where=f"{path} item {i}",
                              expected="the time (s, session clock) the version holds from")
        if lm.id in nodes:
            raise FormatError(f"id {lm.id!r} is a dropped node", where=f"{path} item {i}",
                              expected="a landmark id (nodes are localized by the mission)")
    return tuple(sorted(out, key=lambda v: float(v.updated or 0.0)))


def _read_agents(mfile: Path, entries: Sequence[AgentEntry], nodes: Sequence[str],
                 landmarks: Mapping[str, Landmark], *, repair: bool
                 ) -> dict[str, MissionAgent]:
    agents: dict[str, MissionAgent] = {}
    for i, entry in enumerate(entries):
        folder = mfile.parent / entry.session
        if not folder.exists():
            raise InputError(f"agent {entry.name!r}: no such session {str(folder)!r}",
                             where=f"{mfile} agents[{i}].session",
                             expected="a session folder or zip inside the mission folder")
        if not is_session(folder):
            raise InputError(f"agent {entry.name!r}: {str(folder)!r} is not a session",
                             where=f"{mfile} agents[{i}].session",
                             expected="an hrtls session folder or zip (other recordings: "
                                      "`hrtls convert` first)")
        session = _read_agent(folder, landmarks, repair=repair)
        _warn_unknown(session, nodes, folder)
        agents[entry.name] = MissionAgent(entry.name, entry.kind, folder, session)
    return agents


_UNPLACED = "id(s) not in landmarks.json"


def _read_agent(folder: Path, landmarks: Mapping[str, Landmark], *, repair: bool) -> Session:
    """The agent's session with the mission's landmarks added (its own of the same id win)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            session, _ = check_session_clocks(read_session(folder, repair=repair), repair=repair)
        except InputError as exc:
            # name the agent's folder: every agent has an imu.csv
            if str(folder) in exc.where:
                raise
            raise type(exc)(exc.problem, where=f"{folder}: {exc.where}" if exc.where
                            else str(folder), expected=exc.expected, hint=exc.hint) from None
    for w in caught:
        # ids the session alone cannot place are judged below, against the whole mission
        if issubclass(w.category, DegradedInputWarning) and _UNPLACED in str(w.message):
            continue
        warnings.warn(w.message, w.category, stacklevel=4)
    if landmarks:
        session = session.with_parts(landmarks={**landmarks, **session.landmarks})
    return session


def _warn_unknown(session: Session, nodes: Sequence[str], folder: Path) -> None:
    known = set(nodes)
    for label, ids in session.unknown_ids().items():
        left = [i for i in ids if label != "ranges" or i not in known]
        if left:
            shown = ", ".join(left[:5]) + (" ..." if len(left) > 5 else "")
            where = "network.json nor landmarks.json" if label == "ranges" else "landmarks.json"
            warnings.warn(f"{folder} {label}: {len(left)} id(s) in neither the mission's "
                          f"{where} ({shown})", DegradedInputWarning, stacklevel=3)


def write_mission(path: Path | str, *, agents: Sequence[tuple[str, AgentKind, Session]],
                  nodes: Sequence[str] = (), landmarks: Mapping[str, Landmark] | None = None,
                  name: str = "", notes: Sequence[str] = (),
                  source: Mapping[str, Any] | None = None, overwrite: bool = False) -> Path:
    """Write a mission folder: each agent's session under ``agents/<name>/``, the files above.

    Node truth is not written here (see :func:`write_network_truth`).
    """
    from hrtls.io.session import write_session

    root = Path(path)
    if root.exists() and not root.is_dir():
        raise InputError("exists and is not a folder", where=str(root), expected="a folder path")
    if (root / MISSION_FILE).exists() and not overwrite:
        raise InputError(f"already holds a mission ({MISSION_FILE})", where=str(root),
                         expected="a new or empty folder (or overwrite=True)")
    if not agents:
        raise InputError("no agents", where="mission.json agents", expected="at least one agent")
    text = mission_json([(n, k, f"agents/{n}") for n, k, _ in agents], name=name, notes=notes,
                        source=source)
    _unique(list(nodes), what="node id", where=root / NETWORK_FILE)
    root.mkdir(parents=True, exist_ok=True)
    for n, _, session in agents:
        write_session(session, root / "agents" / n, overwrite=overwrite)
    if nodes:
        (root / NETWORK_FILE).write_text(
            NetworkModel(nodes=[NodeEntry(id=n) for n in nodes]).model_dump_json(
                indent=2, exclude_none=True) + "\n", encoding="utf-8")
    if landmarks:
        items = [lm.model_dump(mode="json", exclude_none=True) for lm in landmarks.values()]
        (root / LANDMARKS_FILE).write_text(json.dumps(items, indent=2) + "\n", encoding="utf-8")
    (root / MISSION_FILE).write_text(text, encoding="utf-8")
    return root


def mission_json(agents: Sequence[tuple[str, AgentKind, str]], *, name: str = "",
                 notes: Sequence[str] = (), source: Mapping[str, Any] | None = None,
                 service: Mapping[str, Any] | None = None) -> str:
    """The text of ``mission.json``; ``agents``: (name, kind, session path in the folder)."""
    where = "mission.json agents"
    try:
        entries = [AgentEntry(name=n, kind=k, session=p) for n, k, p in agents]
        spec = MissionFileModel(format=MISSION_FORMAT, version=MISSION_VERSION, name=name,
                                agents=entries, notes=list(notes), source=dict(source or {}),
                                service=dict(service or {}))
    except ValidationError as exc:
        raise InputError(pydantic_problem(exc), where=where,
                         expected="at least one agent (name usable as a folder, kind "
                                  "rescuer or robot)") from None
    _unique([a.name for a in entries], what="agent name", where=Path(where))
    _unique([a.session for a in entries], what="agent session", where=Path(where))
    return spec.model_dump_json(indent=2, exclude_none=True) + "\n"


def write_network_truth(path: Path | str, node_truth_m: Mapping[str, FloatArray]) -> Path:
    """Write ``network_truth.json`` (true node positions ``[x, y(, z)]``, m) into a folder."""
    out = Path(path) / NETWORK_TRUTH_FILE
    model = NetworkTruthModel(nodes=[
        NodeTruthEntry(id=k, position=tuple(float(x) for x in v))  # type: ignore[arg-type]
        for k, v in node_truth_m.items()])
    out.write_text(model.model_dump_json(indent=2) + "\n", encoding="utf-8")
    return out
