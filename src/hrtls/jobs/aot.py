"""Build the kernels ahead of time into one extension module (``hrtls warmup``).

The kernels numba compiled in this process (each with the argument types it was called with)
are compiled again by ``numba.pycc`` into an extension module in the user cache
(:func:`hrtls.kernels.folder`), with each kernel's own numba options and for this machine's
CPU, as the JIT compiles them. A manifest beside it lists, per kernel, the exported builds with
their argument types, and the sources they came from; :mod:`hrtls.kernels` loads it while
these are unchanged. Building needs a C compiler; without one nothing is written.
"""

from __future__ import annotations

import pickle
import shutil
import sys
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

import hrtls.kernels as K


def arg_spec(ty: Any) -> K.Spec | None:
    """The run-time check of one numba argument type; None when builds do not take it."""
    from numba.core import types
    from numba.np.numpy_support import as_dtype

    if isinstance(ty, types.Array):
        return ("a", as_dtype(ty.dtype), ty.ndim, ty.layout, bool(ty.mutable))
    scalars: dict[Any, tuple[type, ...]] = {
        types.float64: (float, np.float64), types.int64: (int, np.int64),
        types.boolean: (bool, np.bool_)}
    return ("s", scalars[ty]) if ty in scalars else None


def compiled_builds(kernels: Iterable[K.Kernel]) -> list[tuple[K.Kernel, Any, list[K.Spec]]]:
    """(kernel, signature, argument checks) of every build the JIT made of these kernels."""
    out = []
    for kernel in kernels:
        disp = kernel._dispatcher
        if disp is None or kernel.targetoptions.get("inline") == "always":
            continue
        for sig in disp.signatures:
            specs = [arg_spec(t) for t in sig]
            if all(s is not None for s in specs):
                ret = disp.overloads[sig].signature.return_type
                out.append((kernel, ret(*sig), [s for s in specs if s is not None]))
    return out


BLAS_HELPERS = frozenset({"numba_xxdot", "numba_xxgemv", "numba_xxgemm", "numba_xxnrm2"})
"""numba's helpers that call BLAS (``scipy.linalg.cython_blas``); its other ``numba_xx*`` and
``numba_ez_*`` helpers call LAPACK (``scipy.linalg.cython_lapack``)."""


def _llvm_modules(library: Any) -> list[Any]:
    """The LLVM modules of a numba code library and of the libraries it links."""
    out, todo, seen = [], [library], set()
    while todo:
        lib = todo.pop()
        if id(lib) not in seen:
            seen.add(id(lib))
            out.append(lib._final_module)
            todo.extend(getattr(lib, "_linking_libraries", ()))
    return out


def _body(modules: list[Any], name: str) -> Any:
    """The defined function ``name`` in one of ``modules`` (None when only declared)."""
    for module in modules:
        try:
            fn = module.get_function(name)
        except NameError:
            continue
        if not fn.is_declaration:
            return fn
    return None


def scipy_needed(library: Any, name: str) -> set[str]:
    """The scipy modules whose BLAS or LAPACK function ``name`` of ``library`` may call."""
    modules = _llvm_modules(library)
    seen: set[str] = set()
    todo = [name]
    while todo:
        fn = _body(modules, todo.pop())
        for block in fn.blocks if fn is not None else ():
            for ins in block.instructions:
                callee = list(ins.operands)[-1].name if ins.opcode == "call" else ""
                if callee and callee not in seen:
                    seen.add(callee)
                    if not callee.startswith("llvm."):
                        todo.append(callee)
    needed = set()
    for callee in seen:
        if callee in BLAS_HELPERS:
            needed.add("scipy.linalg.cython_blas")
        elif callee.startswith(("numba_xx", "numba_ez_")):
            needed.add("scipy.linalg.cython_lapack")
    return needed


def _flagged_compile(options: dict[Any, dict[str, Any]], needs: dict[Any, set[str]]) -> Any:
    """``compile_extra`` for pycc with each kernel's own numba options (as its dispatcher's).

    ``needs`` receives the scipy modules each kernel may call.
    """
    from numba.core import compiler
    from numba.core.registry import cpu_target

    base = compiler.compile_extra

    def compile_extra(typingctx: Any, targetctx: Any, func: Any, args: Any, return_type: Any,
                      flags: Any, locals: Any, library: Any = None, **kw: Any) -> Any:
        own = compiler.Flags()
        cpu_target.options.parse_as_flags(own, options.get(func, {}))
        for name in ("no_compile", "no_cpython_wrapper", "no_cfunc_wrapper", "nrt"):
            setattr(own, name, getattr(flags, name))
        cres = base(typingctx, targetctx, func, args, return_type, own, locals,
                    library=library, **kw)
        needs.setdefault(func, set()).update(scipy_needed(cres.library, cres.fndesc.llvm_func_name))
        return cres

    return compile_extra


def build(kernels: Iterable[K.Kernel] | None = None, *, where: Path | None = None) -> int:
    """Compile the kernels' JIT builds ahead of time into ``where``; builds written.

    ``kernels``: default every declared kernel. Raises ``OSError`` or the compiler's error
    when the module cannot be built (no C compiler); the folder is then left unchanged.
    """
    import numba
    import numba.pycc.compiler as pycc_compiler
    from numba.pycc import CC

    where = where or K.folder()
    builds = compiled_builds(K.REGISTRY.values() if kernels is None else kernels)
    exports: dict[str, list[tuple[str, list[K.Spec]]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        cc = CC(K.MODULE_NAME)
        cc.output_dir = tmp
        cc.target_cpu = "host"
        cc.verbose = False
        for i, (kernel, sig, specs) in enumerate(builds):
            symbol = f"k{i}"
            cc.export(symbol, sig)(kernel.py_func)
            exports.setdefault(kernel.key, []).append((symbol, specs))
        saved = pycc_compiler.compile_extra
        needs: dict[Any, set[str]] = {}
        pycc_compiler.compile_extra = _flagged_compile(
            {k.py_func: k.dispatcher.targetoptions for k, _, _ in builds}, needs)
        try:
            cc.compile()
        finally:
            pycc_compiler.compile_extra = saved
        built = next(Path(tmp).glob(f"{K.MODULE_NAME}*"))
        sources = sorted({sys.modules[k.py_func.__module__].__file__ or ""
                          for k in K.REGISTRY.values()} - {""} | {numba.__file__})
        # a new name each build: a process may still map the older one
        name = f"{K.MODULE_NAME}-{time.time_ns():x}{''.join(built.suffixes)}"
        manifest = {"file": name, "exports": exports, "sources": K.source_stamps(sources),
                    "scipy": {k.key: sorted(needs.get(k.py_func, ())) for k, _, _ in builds}}
        where.mkdir(parents=True, exist_ok=True)
        (where / K.MANIFEST).unlink(missing_ok=True)
        for old in where.glob(f"{K.MODULE_NAME}-*"):
            old.unlink()
        shutil.copy2(built, where / name)
        with open(where / (K.MANIFEST + ".tmp"), "wb") as fh:
            pickle.dump(manifest, fh)
        (where / (K.MANIFEST + ".tmp")).replace(where / K.MANIFEST)
    K.reset()
    return len(builds)
