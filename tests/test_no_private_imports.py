"""No hrtls module reaches into another module's private names.

Two rules, checked on the source (AST):

* over all of ``src/hrtls``: no ``from hrtls.x import _y`` (a private name of another module),
  and a private module (``hrtls.sim._speed_profile``) is imported only from inside its own
  package;
* in ``hrtls.mission``, ``hrtls.sim`` and ``hrtls.service``: no ``obj._name`` on anything but
  ``self`` / ``cls`` (modules use each other's public interface, e.g.
  :meth:`MissionTracker.agent_rows`), listed exceptions aside.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "hrtls"
CHECKED = [PACKAGE / "mission", PACKAGE / "sim", PACKAGE / "service"]

ALLOWED_IMPORTS: dict[str, set[str]] = {
    "hrtls.io.stream": {"from hrtls.io.csvtable import _header",
                        "from hrtls.io.session import _group",
                        "from hrtls.io.session import _read_landmarks",
                        "from hrtls.io.session import _read_meta",
                        "from hrtls.io.session import _read_vector_file",
                        "from hrtls.io.session import _SessionFiles"},
    "hrtls.runner.ray_live": {"from hrtls.runner.ray_engine import _import_ray"},
    # helpers of the private module hrtls.wsn._propagation, used inside hrtls.wsn
    "hrtls.wsn._propagation_reference": {"from hrtls.wsn._propagation import _circle_candidates",
                                         "from hrtls.wsn._propagation import _gdop2"},
    "hrtls.wsn.shadow_edge": {"from hrtls.wsn._propagation import _circle_candidates"},
    "hrtls.wsn.trilateration": {"from hrtls.wsn._propagation import _lls_gn",
                                "from hrtls.wsn._propagation import _min_spread"},
}
"""Today's exceptions to the import rule, module -> imports (to be made public, not grown)."""

ALLOWED_ATTRIBUTES: dict[str, set[str]] = {
    # offline_tracker drives a MissionRunner, a class of the same module
    "hrtls/service/mission_runner.py": {"_open_new", "_consume"},
}
"""Module (relative to src) -> private attributes it may use on objects other than self."""


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def module_name(path: Path) -> str:
    """Dotted name of a module file under ``src``."""
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _package_of(module: str, path: Path) -> str:
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


def _resolve(node: ast.ImportFrom, package: str) -> str:
    """Absolute module of a ``from ... import`` (relative imports resolved on ``package``)."""
    if node.level == 0:
        return node.module or ""
    base = package.split(".")
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _private_module_ok(target: str, package: str) -> bool:
    """A private module (any private component) imported from inside its own package."""
    parts = target.split(".")
    for k, p in enumerate(parts):
        if _private(p):
            owner = ".".join(parts[:k])
            if not (package == owner or package.startswith(owner + ".")):
                return False
    return True


def private_imports(source: str, *, module: str, package: str) -> list[str]:
    """``module``'s imports of private hrtls names, and of private modules from outside."""
    bad: list[str] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names if a.name.split(".")[0] == "hrtls"]
            bad += [f"import {t}" for t in targets if not _private_module_ok(t, package)]
        elif isinstance(node, ast.ImportFrom):
            src = _resolve(node, package)
            if src.split(".")[0] != "hrtls":
                continue
            for a in node.names:
                full = f"{src}.{a.name}"
                private_name = _private(a.name) and not (
                    _is_module(full) and _private_module_ok(full, package))
                if private_name or not _private_module_ok(src, package):
                    bad.append(f"from {src} import {a.name}")
    return bad


def _is_module(dotted: str) -> bool:
    rel = Path(*dotted.split("."))
    return (SRC / rel).with_suffix(".py").is_file() or (SRC / rel / "__init__.py").is_file()


def foreign_private_attributes(source: str) -> list[str]:
    """``obj._name`` where ``obj`` is not ``self`` / ``cls`` (line: expression)."""
    bad: list[tuple[int, int, str]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            owner = node.value
            if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
                continue
            bad.append((node.lineno, node.col_offset, ast.unparse(node)))
    return [f"{line}: {text}" for line, _, text in sorted(bad)]


def test_rules_catch_what_they_should() -> None:
    src = ("from hrtls.mission.tracker import _known_ids, MissionTracker\n"
           "from .tracker import _x\nimport hrtls.sim._speed_profile\n"
           "from hrtls.sim._speed_profile import still_headings\n"
           "from hrtls.sim import _speed_profile\nfrom os import _exit\n")
    got = private_imports(src, module="hrtls.mission.peers", package="hrtls.mission")
    assert got == ["from hrtls.mission.tracker import _known_ids",
                   "from hrtls.mission.tracker import _x", "import hrtls.sim._speed_profile",
                   "from hrtls.sim._speed_profile import still_headings",
                   "from hrtls.sim import _speed_profile"]
    assert private_imports(src, module="hrtls.sim.x", package="hrtls.sim") == [
        "from hrtls.mission.tracker import _known_ids", "from hrtls.sim.tracker import _x"]
    attrs = foreign_private_attributes(
        "def f(mt, self):\n    mt._apply(1)\n    self._ok()\n    x = mt.a._b\n    mt.__len__()\n")
    assert attrs == ["2: mt._apply", "4: mt.a._b"]


def test_no_module_imports_a_private_name_of_another() -> None:
    offenders: dict[str, list[str]] = {}
    seen: dict[str, set[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        mod = module_name(path)
        found = private_imports(path.read_text(encoding="utf-8"), module=mod,
                                package=_package_of(mod, path))
        extra = [f for f in found if f not in ALLOWED_IMPORTS.get(mod, set())]
        if extra:
            offenders[mod] = extra
        seen[mod] = set(found)
    assert not offenders, f"private imports across hrtls modules: {offenders}"
    stale = {m: sorted(v - seen.get(m, set())) for m, v in ALLOWED_IMPORTS.items()
             if v - seen.get(m, set())}
    assert not stale, f"exceptions no longer needed, remove them from ALLOWED_IMPORTS: {stale}"


def test_mission_sim_service_use_only_public_members_of_other_objects() -> None:
    offenders: dict[str, list[str]] = {}
    for path in sorted(p for pkg in CHECKED for p in pkg.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        allowed = ALLOWED_ATTRIBUTES.get(rel, set())
        found = [f for f in foreign_private_attributes(path.read_text(encoding="utf-8"))
                 if f.rpartition(".")[2] not in allowed]
        if found:
            offenders[rel] = found
    assert not offenders, f"private members used from outside their object: {offenders}"
