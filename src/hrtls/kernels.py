"""The compiled kernels: ahead-of-time compiled when built, numba's JIT otherwise.

Every numerical kernel is declared with :func:`njit` (numba's options). The declaration
imports nothing: a :class:`Kernel` calls, for arguments of a type it was built for, the same
function compiled ahead of time into an extension module (``hrtls warmup`` builds it, see
:mod:`hrtls.jobs.aot`), which runs without importing numba or loading its cache; for any other
call it makes numba's dispatcher (``cache=True`` as before) and calls that. The JIT path is the
reference: the two compile the same Python with the same options for the same CPU.

The built module is used while the sources it was compiled from are unchanged (their sizes and
modification times are in its manifest); ``HRTLS_AOT=0`` turns it off.
"""

from __future__ import annotations

import os
import pickle
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

try:
    import fcntl
except ImportError:  # pragma: no cover (Windows: no cross-process compile lock)
    fcntl = None  # type: ignore[assignment]

ENV_SWITCH = "HRTLS_AOT"
"""Set to ``0`` to call the JIT kernels only."""
MODULE_NAME = "hrtls_aot_kernels"
"""Name of the ahead-of-time compiled extension module."""
MANIFEST = "manifest.pkl"
"""File beside the extension: the exports by kernel, their argument types, the sources."""
COMPILE_LOG = "HRTLS_COMPILE_LOG"
"""A file to append one JSON line to per compile of a kernel signature (profiling; unset: off).
"""

_LOCK = threading.RLock()
REGISTRY: dict[str, Kernel] = {}
"""Every declared kernel by ``module:qualname``."""
_STATE: dict[str, Any] = {"aot": None, "numba": None, "scipy": {}}

_HELD: set[str] = set()
"""Compile locks this process holds (changed under numba's compiler lock only)."""
Spec = tuple[Any, ...]
"""One argument type: ``("a", dtype, ndim, layout, writable)`` for arrays, ``("s", types)``
for scalars (the Python types numba gives that scalar type)."""


class Kernel:
    """A numba kernel made on first use, or its ahead-of-time compiled build."""

    def __init__(self, py_func: Callable[..., Any], options: dict[str, Any]) -> None:
        self.py_func = py_func
        self.options = options
        self.targetoptions = {k: v for k, v in options.items() if k != "cache"}
        self.key = f"{py_func.__module__}:{py_func.__qualname__}"
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = py_func
        self._dispatcher: Any = None
        self._aot: tuple[tuple[Callable[..., Any], Callable[[tuple[Any, ...]], bool]], ...] | None
        self._aot = None
        if self.key not in REGISTRY:
            REGISTRY[self.key] = self

    @property
    def dispatcher(self) -> Any:
        """The numba dispatcher of this kernel (made, and numba imported, on first use)."""
        if self._dispatcher is None:
            with _LOCK:
                if self._dispatcher is None:
                    self._dispatcher = cooperative(_numba().njit(**self.options)(self.py_func))
        return self._dispatcher

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        """The first build whose argument types fit, else numba's dispatcher."""
        aot = self._aot
        if aot is None:
            aot = self._aot = exports(self.key)
        if not kwargs:
            for fn, fits in aot:
                if fits(args):
                    return fn(*args)
        return self.dispatcher(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("_dispatcher", "_aot"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self) -> str:
        return f"Kernel({self.key})"

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        return declared, (self.key,)


def declared(key: str) -> Kernel:
    """The kernel declared as ``module:qualname`` (its module imported)."""
    import importlib

    module = key.partition(":")[0]
    importlib.import_module(module)
    return REGISTRY[key]


def njit(**options: Any) -> Callable[[Callable[..., Any]], Kernel]:
    """Declare a kernel with numba's ``njit`` options (imports nothing yet)."""

    def declare(fn: Callable[..., Any]) -> Kernel:
        return Kernel(fn, options)

    return declare


def _numba() -> Any:
    """The numba module, imported once; kernels are typed as their dispatchers inside others."""
    mod = _STATE["numba"]
    if mod is None:
        with _LOCK:
            mod = _STATE["numba"]
            if mod is None:
                import numba
                from numba.core import types
                from numba.extending import typeof_impl

                @typeof_impl.register(Kernel)
                def _typeof_kernel(val: Kernel, c: Any) -> Any:
                    return types.Dispatcher(val.dispatcher)

                mod = _STATE["numba"] = numba
    return mod


def cooperative(dispatcher: Any) -> Any:
    """The dispatcher, compiling one signature at a time across processes (its cache locked).

    numba's cache of a kernel is an index file and numbered data files, updated without a
    lock: two processes saving overloads of one kernel at once could pair a signature with the
    other's code. Each compile here holds numba's compiler lock, then an exclusive lock on a
    file beside the kernel's index; the cache is read and written inside it, so a process
    waiting for another's compile then loads that build. Without ``fcntl`` (or a writable
    cache) nothing changes.
    """
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    index = getattr(cache_file, "_index_path", None)
    if index is None or fcntl is None:
        return dispatcher
    from numba.core.compiler_lock import global_compiler_lock

    compile_one = dispatcher.compile
    lock_path = f"{index}.lock"
    log = os.environ.get(COMPILE_LOG)
    if log:
        compile_one = _logged(dispatcher, compile_one, log)

    def compile(sig: Any) -> Any:
        with global_compiler_lock:
            if lock_path in _HELD:  # a compile of this kernel within its own compile
                return compile_one(sig)
            try:
                handle = open(lock_path, "ab")  # noqa: SIM115 (held across the compile)
            except OSError:
                return compile_one(sig)
            with handle:
                waited = time.perf_counter()
                fcntl.flock(handle, fcntl.LOCK_EX)  # released when the file closes
                _NESTED.wait_s = time.perf_counter() - waited
                _HELD.add(lock_path)
                try:
                    return compile_one(sig)
                finally:
                    _HELD.discard(lock_path)

    dispatcher.compile = compile
    return dispatcher


_NESTED = threading.local()
"""Per thread: CPU seconds of the compiles nested in the one in progress; the last lock wait."""


def _logged(dispatcher: Any, compile_one: Callable[[Any], Any], log: str
            ) -> Callable[[Any], Any]:
    """``compile_one`` appending a JSON line per call to ``log`` (:data:`COMPILE_LOG`).

    The line: process id and command, kernel, signature, whether numba compiled it (not
    loaded from its cache), start (Unix time), wall and CPU seconds of the call, CPU seconds
    less the nested compiles of other kernels (``self_cpu_s``), nesting depth, lock wait.
    """
    import json

    name = f"{dispatcher.py_func.__module__}:{dispatcher.py_func.__qualname__}"

    def compile(sig: Any) -> Any:
        outer = getattr(_NESTED, "stack", None)
        if outer is None:
            outer = _NESTED.stack = []
        wait_s = getattr(_NESTED, "wait_s", 0.0)
        _NESTED.wait_s = 0.0
        misses = sum(dispatcher._cache_misses.values())
        start, wall0, cpu0 = time.time(), time.perf_counter(), time.thread_time()
        outer.append(0.0)
        try:
            return compile_one(sig)
        finally:
            cpu = time.thread_time() - cpu0
            nested = outer.pop()
            if outer:
                outer[-1] += cpu
            line = {"pid": os.getpid(), "argv": " ".join(sys.argv[:2]), "kernel": name,
                    "sig": str(sig), "depth": len(outer),
                    "compiled": sum(dispatcher._cache_misses.values()) > misses,
                    "start": start, "wall_s": time.perf_counter() - wall0, "cpu_s": cpu,
                    "self_cpu_s": cpu - nested, "wait_s": wait_s}
            try:
                with open(log, "a", encoding="utf-8") as fh:
                    fh.write(json.dumps(line) + "\n")
            except OSError:
                pass

    return compile


def folder() -> Path:
    """Where the ahead-of-time build of this install lives (under the user cache)."""
    import zlib

    import hrtls

    base = os.environ.get("XDG_CACHE_HOME")
    root = (Path(base) if base else Path.home() / ".cache") / "hrtls" / "aot"
    where = str(Path(hrtls.__file__).resolve().parent)
    tag = f"{hrtls.__version__}-py{sys.version_info[0]}{sys.version_info[1]}"
    return root / f"{tag}-{zlib.crc32(where.encode()):08x}"


def source_stamps(paths: list[str]) -> list[tuple[str, int, int]]:
    """(path, mtime ns, size) of each file; -1s for a missing one."""
    out = []
    for p in paths:
        try:
            st = os.stat(p)
            out.append((p, st.st_mtime_ns, st.st_size))
        except OSError:
            out.append((p, -1, -1))
    return out


Table = dict[str, list[tuple[Callable[..., Any], Callable[[tuple[Any, ...]], bool]]]]
"""The builds of each kernel (by key): the compiled function and its argument check."""


def _load() -> Table:
    """The builds of this install (:func:`folder`); empty when off, missing or stale."""
    if os.environ.get(ENV_SWITCH, "1") == "0":
        return {}
    table, _STATE["scipy"] = load_builds(folder())
    return table


def load_builds(where: Path) -> tuple[Table, dict[str, list[str]]]:
    """The builds of the module in ``where`` and the scipy modules each kernel's builds call.

    Both are empty when the module is missing or its sources changed.
    """
    try:
        with open(where / MANIFEST, "rb") as fh:
            manifest = pickle.load(fh)
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError):
        return {}, {}
    stamps = manifest["sources"]
    if source_stamps([s[0] for s in stamps]) != stamps:
        return {}, {}
    import importlib.machinery
    import importlib.util

    path = str(where / manifest["file"])
    try:
        loader = importlib.machinery.ExtensionFileLoader(MODULE_NAME, path)
        spec = importlib.util.spec_from_file_location(MODULE_NAME, path, loader=loader)
        assert spec is not None
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
    except (ImportError, OSError, AssertionError):
        return {}, {}
    return ({key: [(getattr(module, sym), guard(specs)) for sym, specs in entries]
             for key, entries in manifest["exports"].items()}, manifest.get("scipy", {}))


def exports(key: str) -> tuple[tuple[Callable[..., Any], Callable[[tuple[Any, ...]], bool]],
                               ...]:
    """The ahead-of-time builds of one kernel (none when there is no usable build)."""
    table = _STATE["aot"]
    if table is None:
        with _LOCK:
            table = _STATE["aot"]
            if table is None:
                table = _STATE["aot"] = _load()
    builds = tuple(table.get(key, ()))
    for name in _STATE.get("scipy", {}).get(key, ()) if builds else ():
        preload_cython(name)
    return builds


def preload_cython(name: str) -> None:
    """Load scipy's ``scipy.linalg.cython_blas`` (or ``cython_lapack``) extension alone.

    numba's BLAS and LAPACK helpers import it on their first call to take its functions;
    importing it by name first runs ``scipy.linalg``'s ``__init__``, several times slower.
    Loaded here, the helpers find it in ``sys.modules``; it is the same compiled module.
    On any failure nothing is done (the helpers then import it as usual).
    """
    if name in sys.modules:
        return
    import importlib.machinery
    import importlib.util

    try:
        spec = importlib.util.find_spec("scipy")
        if spec is None or spec.origin is None:
            return
        base = Path(spec.origin).parent.joinpath(*name.split(".")[1:])
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = base.with_name(base.name + suffix)
            if path.exists():
                loader = importlib.machinery.ExtensionFileLoader(name, str(path))
                found = importlib.util.spec_from_file_location(name, path, loader=loader)
                if found is None:
                    return
                module = importlib.util.module_from_spec(found)
                loader.exec_module(module)
                sys.modules[name] = module
                return
    except (ImportError, OSError):
        return


def jit_only() -> None:
    """Call the JIT kernels only, whatever is built (until :func:`reset`)."""
    with _LOCK:
        _STATE["aot"] = {}
        for k in REGISTRY.values():
            k._aot = None


def reset() -> None:
    """Forget the loaded build (the next call of each kernel looks again)."""
    with _LOCK:
        _STATE["aot"] = None
        for k in REGISTRY.values():
            k._aot = None


def array_layout(a: np.ndarray) -> str:
    """The numba layout letter of an array."""
    flags = a.flags
    return "C" if flags.c_contiguous else "F" if flags.f_contiguous else "A"


def guard(specs: list[Spec]) -> Callable[[tuple[Any, ...]], bool]:
    """Whether arguments have the types of one build (the types numba would give them)."""
    n = len(specs)

    def fits(args: tuple[Any, ...]) -> bool:
        if len(args) != n:
            return False
        for a, s in zip(args, specs, strict=True):
            if s[0] == "a":
                if (type(a) is not np.ndarray or a.ndim != s[2] or a.dtype != s[1]
                        or (s[4] and not a.flags.writeable)
                        or array_layout(a) != s[3]):
                    return False
            elif type(a) not in s[1]:
                return False
        return True

    return fits
