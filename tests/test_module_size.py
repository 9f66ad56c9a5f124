"""No module of the package grows past MAX_LINES (split it by responsibility instead)."""

from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "hrtls"
MAX_LINES = 600
ALLOWED: set[str] = set()  # modules still too long, to be split, then removed from this set


def line_counts(root: Path) -> dict[str, int]:
    """Lines of every ``.py`` file below ``root``, by path relative to it (``/`` separated)."""
    return {p.relative_to(root).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
            for p in sorted(root.rglob("*.py"))}


def oversized(counts: dict[str, int], limit: int, allowed: set[str]) -> dict[str, int]:
    """The modules over ``limit`` lines that are not allowed to be."""
    return {name: n for name, n in counts.items() if n > limit and name not in allowed}


def test_line_counts_and_limit_on_a_small_tree(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("x = 1\n" * 5)
    (tmp_path / "sub" / "b.py").write_text("y = 2\n" * 3 + "z = 3")  # no final newline
    (tmp_path / "notes.txt").write_text("ignored\n" * 100)
    counts = line_counts(tmp_path)
    assert counts == {"a.py": 5, "sub/b.py": 4}
    assert oversized(counts, 4, set()) == {"a.py": 5}
    assert oversized(counts, 4, {"a.py"}) == {}
    assert oversized(counts, 3, {"a.py"}) == {"sub/b.py": 4}


def test_no_module_over_the_limit() -> None:
    too_long = oversized(line_counts(PACKAGE), MAX_LINES, ALLOWED)
    assert not too_long, f"modules over {MAX_LINES} lines (split them): {too_long}"


def test_allowed_modules_are_still_long() -> None:
    """An allowed module that was shrunk (or removed) leaves the list."""
    counts = line_counts(PACKAGE)
    stale = sorted(name for name in ALLOWED if counts.get(name, 0) <= MAX_LINES)
    assert not stale, f"remove from ALLOWED (now at most {MAX_LINES} lines): {stale}"
