"""`njit` for psrt's kernels: numba's, with an on-disk cache keyed by what a kernel depends on.

numba reuses cached machine code while the decorated function's own file is unchanged, so a
kernel that inlines helpers from another module would keep running stale code after an edit
there, and a kernel specialised per variant (drivers.make_search) that calls another one is
never found again (a pickled dispatcher differs from process to process). Here a kernel's
cache key is its bytecode and constants, its specialised globals (see specialise: constants
by value, kernels it calls by their own keys) and the sources of the
psrt modules its module imports, transitively: editing one module recompiles what depends on
it, nothing else.
"""
from __future__ import annotations

import hashlib
import re
import sys
import types
from functools import lru_cache
from pathlib import Path

import numba
from numba.core.caching import FunctionCache, IndexDataCacheFile
from numba.core.registry import CPUDispatcher

PACKAGE = Path(__file__).resolve().parent


def _one_scope_copy_per_inline() -> None:
    """numba's inliner deep-copies a callee's IR block by block, each block with a memo of its
    own, so every block copies the callee's whole variable scope again: quadratic in the size
    of a deeply inlined kernel (over a minute of the search's compile). Blocks of one function
    share one scope, so one copy of it per inline is enough, and is what numba then expects
    ("one function should only have one local scope"). Compilation holds numba's compiler
    lock, so one table of the copies made during the current inline serves."""
    import copy

    from numba.core import inline_closurecall, ir

    if getattr(ir.Scope, "_psrt_one_copy", False):
        return
    copies = {}

    def deepcopy_scope(self, memo):
        made = copies.get(id(self))
        if made is not None and made[0] is self:
            memo[id(self)] = made[1]
            return made[1]
        dup = ir.Scope.__new__(ir.Scope)
        memo[id(self)] = dup
        copies[id(self)] = (self, dup)
        for key, value in self.__dict__.items():
            setattr(dup, key, copy.deepcopy(value, memo))
        return dup

    inline_ir = inline_closurecall.InlineWorker.inline_ir

    def inline_ir_one_scope_copy(self, *args, **kwargs):
        try:
            return inline_ir(self, *args, **kwargs)
        finally:
            copies.clear()

    ir.Scope.__deepcopy__ = deepcopy_scope
    ir.Scope._psrt_one_copy = True
    inline_closurecall.InlineWorker.inline_ir = inline_ir_one_scope_copy


_one_scope_copy_per_inline()


def _untyped_ir_once_per_callee() -> None:
    """numba re-runs a callee's whole untyped pipeline (bytecode to IR, its own inlining, branch
    pruning) at every call site it inlines: the search's helpers were translated 150 times.
    The IR comes out the same each time for the same function and flags, and inline_ir copies
    it before changing anything, so inline_function makes it once and reuses it. (Typed
    inlining of overloads mutates the IR it gets, so run_untyped_passes itself stays as is.)"""
    from numba.core import inline_closurecall

    worker = inline_closurecall.InlineWorker
    if getattr(worker, "_psrt_memo", False):
        return
    made = {}

    def inline_function(self, caller_ir, block, i, function, arg_typs=None):
        key = (function, self.flags.nrt, self.flags.error_model, self.flags.no_rewrites)
        if key not in made:
            made[key] = self.run_untyped_passes(function)
        self.flags.enable_ssa = False  # what run_untyped_passes leaves behind, as before
        return self.inline_ir(caller_ir, block, i, made[key], function.__code__.co_freevars,
                              arg_typs=arg_typs)

    worker.inline_function = inline_function
    worker._psrt_memo = True


_untyped_ir_once_per_callee()


_RELATIVE_IMPORT = re.compile(rb"^\s*from \.([\w.]*) import ([\w, ()]+)", re.MULTILINE)


@lru_cache(maxsize=None)
def _imports(module_path: Path) -> tuple:
    """The psrt modules (paths) a module imports relatively (a scan of its lines: parsing the
    sources would cost a fresh process a few tenths of a second before its first frame)."""
    found = []
    for module, names in _RELATIVE_IMPORT.findall(module_path.read_bytes()):
        candidates = [module.decode()] if module else [n.strip() for n in names.decode().strip("()").split(",")]
        for name in candidates:
            candidate = module_path.parent.joinpath(*name.split(".")).with_suffix(".py")
            if candidate.is_file():
                found.append(candidate)
    return tuple(sorted(set(found)))


@lru_cache(maxsize=None)
def dependency_key(module_path: Path) -> str:
    """Hash of a module's source and of every psrt module it imports, transitively."""
    seen, todo = set(), [module_path]
    while todo:
        path = todo.pop()
        if path not in seen:
            seen.add(path)
            todo.extend(_imports(path))
    digest = hashlib.sha256()
    for path in sorted(seen):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def specialise(template, **constants):
    """A copy of the Python function `template` that sees `constants` as module globals: numba
    freezes globals at compile time, so flags become constants its branches are pruned by, and
    kernels named there are called (or inlined) directly.

    Globals, not a closure: numba deep-copies a closure's cell contents each time it inlines
    the function, and a kernel held in a cell drags its whole compiled library along.

    Each copy's qualified name carries its key. numba names machine code by qualified name,
    argument types and a counter that is only unique within one process, and links a callee
    into each caller as a "one definition" symbol: two variants of the search cached by
    different processes under the same counter value had one symbol name, and a process that
    loaded both ran one variant's search for the other (an f32 trace, then a rational render:
    2 hits where there were 14)."""
    namespace = dict(template.__globals__)
    namespace.update(constants)
    func = types.FunctionType(template.__code__, namespace, template.__name__, template.__defaults__)
    func.__doc__ = template.__doc__
    func.__psrt_constants__ = constants
    func.__qualname__ = f"{template.__qualname__}__{function_key(func)[:16]}"
    return func


def _value_key(value) -> str:
    if isinstance(value, CPUDispatcher):
        return function_key(value.py_func)
    return repr(value)


def function_key(func) -> str:
    """Bytecode, constants and specialised globals of a Python function, kernels among them by
    their own keys."""
    digest = hashlib.sha256(func.__code__.co_code)
    digest.update(repr(func.__code__.co_consts).encode())
    for name, value in sorted(getattr(func, "__psrt_constants__", {}).items()):
        digest.update(f"{name}={_value_key(value)};".encode())
    for cell in func.__closure__ or ():
        digest.update(_value_key(cell.cell_contents).encode())
    return digest.hexdigest()


class _KeyedDataFiles(IndexDataCacheFile):
    """numba's index and data files, with each data file named by its entry's key instead of the
    index's next free number: two processes saving different entries of one function at once
    (the f32 and f64 kernels of a variant share a dispatcher) could give both the same number,
    and the index kept by one could name the machine code written by the other. Now a race
    can only lose an index entry (compiled again later). The data goes first, so the index never
    names a file that is not there yet."""

    def save(self, key, data):
        data_name = f"{self._index_name[:-len('.nbi')]}.{hashlib.sha256(repr(key).encode()).hexdigest()[:24]}.nbc"
        self._save_data(data_name, data)
        overloads = self._load_index()
        overloads[key] = data_name
        self._save_index(overloads)


class _KernelCache(FunctionCache):
    def __init__(self, py_func):
        super().__init__(py_func)
        self._cache_file = _KeyedDataFiles(self._cache_path, self._impl.filename_base,
                                           self._impl.locator.get_source_stamp())

    def _index_key(self, sig, codegen):
        module = sys.modules[self._py_func.__module__]
        return (sig, codegen.magic_tuple(), (function_key(self._py_func), dependency_key(Path(module.__file__))))

    def signatures(self, codegen) -> list:
        """The signatures this cache holds current machine code for."""
        return [key[0] for key in self._cache_file._load_index() if key == self._index_key(key[0], codegen)]


def _separate_callees(func, seen: set):
    """The kernels func calls that numba compiles apart from it (not inline='always'), named in
    its specialised globals or theirs, callees before their callers."""
    for value in getattr(func, "__psrt_constants__", {}).values():
        if isinstance(value, CPUDispatcher) and id(value) not in seen:
            seen.add(id(value))
            yield from _separate_callees(value.py_func, seen)
            if value.targetoptions.get("inline", "never") != "always":
                yield value


def load_callees_first(kernel) -> None:
    """Load the cached machine code of the kernels `kernel` calls before its own.

    numba links a copy of each callee into its caller's code and optimises it again there; the
    process that compiles the caller loads the callee's own code first, and the caller's calls
    go to that (a repeated definition binds to the first one loaded). A process that finds the
    caller in the cache loaded only the caller, with its copies: the bundle search's copy, run
    from the cache, took 8 % longer a frame than its own code (float 8x8, teapot 512²). Loaded
    first, each callee runs its own code in every process."""
    from numba.core.registry import cpu_target

    codegen = cpu_target.target_context.codegen()
    for callee in _separate_callees(kernel.py_func, set()):
        if isinstance(callee._cache, _KernelCache):
            for sig in callee._cache.signatures(codegen):
                callee.compile(sig)


def njit(*args, cache=False, **options):
    """numba.njit; with cache=True, cached under the dependency-aware key above."""
    def wrap(func):
        dispatcher = numba.njit(**options)(func)
        if cache and not numba.config.DISABLE_JIT:
            dispatcher._cache = _KernelCache(func)
        return dispatcher
    if args and callable(args[0]):
        return wrap(args[0])
    return wrap
