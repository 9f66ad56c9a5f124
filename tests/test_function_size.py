"""No function of the package grows past MAX_FUNCTION_LINES (compiled kernels excepted)."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "hrtls"
MAX_FUNCTION_LINES = 80
COMPILERS = {"njit", "jit", "vectorize", "guvectorize", "cfunc"}
ALLOWED = {
    # a database migration: one statement per table, frozen once released
    "service/migrations/versions/0001_initial_schema.py:upgrade",
}


def compiled(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Whether a numba decorator (``@njit``, ``@numba.njit(...)`` ...) compiles the function."""
    for dec in fn.decorator_list:
        node = dec.func if isinstance(dec, ast.Call) else dec
        name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
        if name in COMPILERS:
            return True
    return False


def function_lengths(root: Path) -> dict[str, int]:
    """Lines of every function below ``root`` that is not compiled, by ``path:name``."""
    out: dict[str, int] = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not compiled(node):
                assert node.end_lineno is not None
                key = f"{rel}:{node.name}"
                out[key] = max(out.get(key, 0), node.end_lineno - node.lineno + 1)
    return out


def test_function_lengths_on_a_small_tree(tmp_path: Path) -> None:
    body = "".join(f"    x{i} = {i}\n" for i in range(5))
    (tmp_path / "a.py").write_text(
        f"import numba\n\n\ndef long():\n{body}\n\n@numba.njit(cache=True)\ndef kernel():\n"
        f"{body}\n\nclass C:\n    def method(self):\n        return 1\n")
    assert function_lengths(tmp_path) == {"a.py:long": 6, "a.py:method": 2}


def test_no_function_over_the_limit() -> None:
    too_long = {k: n for k, n in function_lengths(PACKAGE).items()
                if n > MAX_FUNCTION_LINES and k not in ALLOWED}
    assert not too_long, f"functions over {MAX_FUNCTION_LINES} lines (split them): {too_long}"


def test_allowed_functions_are_still_long() -> None:
    lengths = function_lengths(PACKAGE)
    stale = sorted(k for k in ALLOWED if lengths.get(k, 0) <= MAX_FUNCTION_LINES)
    assert not stale, f"remove from ALLOWED (now at most {MAX_FUNCTION_LINES} lines): {stale}"
