"""``hrtls.io`` is below ``hrtls.datasets``: no module of it imports the datasets layer."""

import ast
from pathlib import Path

IO_PACKAGE = Path(__file__).resolve().parents[2] / "src" / "hrtls" / "io"
FORBIDDEN = "hrtls.datasets"


def imported_modules(source: str) -> set[str]:
    """Every module an ``import`` names in ``source``, at any depth (lazy imports included)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            out.update(f"{node.module}.{alias.name}" for alias in node.names)
    return out


def reaches(modules: set[str], package: str) -> set[str]:
    """The modules of ``modules`` that are ``package`` or inside it."""
    return {m for m in modules if m == package or m.startswith(package + ".")}


def test_imported_modules_sees_lazy_and_from_imports() -> None:
    src = ("import os\nfrom hrtls import datasets\n\n\ndef f():\n"
           "    from hrtls.datasets.broad import load_trial\n    import hrtls.datasets\n")
    found = imported_modules(src)
    assert reaches(found, FORBIDDEN) == {"hrtls.datasets", "hrtls.datasets.broad",
                                         "hrtls.datasets.broad.load_trial"}
    assert not reaches(imported_modules("from hrtls.datasetsx import y\n"), FORBIDDEN)


def test_io_imports_nothing_from_datasets() -> None:
    offenders = {p.relative_to(IO_PACKAGE).as_posix(): sorted(found)
                 for p in sorted(IO_PACKAGE.rglob("*.py"))
                 if (found := reaches(imported_modules(p.read_text(encoding="utf-8")),
                                      FORBIDDEN))}
    assert not offenders, f"hrtls.io modules importing {FORBIDDEN}: {offenders}"
