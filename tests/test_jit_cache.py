"""The kernel cache (tracer/jit.py): specialised kernels keep machine code of their own across
processes, and concurrent saves never make one entry name another's code."""
from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest
from numba.core import bytecode

from tracer.jit import _KeyedDataFiles, _separate_callees, njit, specialise
from tracer.variants import Variant

pytestmark = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="compiles kernels")


def _scaled(x):
    return x * FACTOR  # noqa: F821 (specialise's)


def _scaled_plus_one(x):
    return scaled(x) + 1.0  # noqa: F821 (specialise's)


def _plus_one_inlined(x):
    return plus_one(x)  # noqa: F821 (specialise's)


def test_specialised_copies_get_symbols_of_their_own_whatever_numba_s_counter_says(monkeypatch):
    """numba names machine code by qualified name, argument types and a per-process counter; two
    processes can give two variants the same counter value. Forced here: the names must still
    differ, or a process loading both from the cache runs one variant's code for the other."""
    names = []
    for factor in (2.0, 3.0):
        monkeypatch.setattr(bytecode.FunctionIdentity, "_unique_ids", itertools.count(900))
        kernel = njit(nogil=True)(specialise(_scaled, FACTOR=factor))
        assert kernel(1.5) == 1.5 * factor
        names.append(kernel.overloads[kernel.signatures[0]].fndesc.mangled_name)
    assert "v900" in names[0] and "v900" in names[1]
    assert names[0] != names[1]


def test_specialised_names_are_the_same_in_every_process():
    """The name follows the kernel's key, so a fresh process finds the same cache entry."""
    from tracer.drivers import make_search
    variant = Variant("f32", True, False, False, True, False, True, "closest", "bvh", False, False)
    code = ("from tracer.drivers import make_search; from tracer.variants import Variant; "
            f"print(make_search(Variant(*{tuple(variant)!r}), False).py_func.__qualname__)")
    here = make_search(variant, False).py_func.__qualname__
    there = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           timeout=300).stdout.strip()
    assert here == there and "__" in here
    assert make_search(variant._replace(trace=False), False).py_func.__qualname__ != here


def test_two_saves_from_stale_indexes_never_name_each_other_s_code(tmp_path, monkeypatch):
    """Two processes that read the index before either saved: each writes its entry against the
    index it read. The second index wins and the first entry is lost (compiled again later), but
    no key may name the other's data, as numba's numbered data files did."""
    first = _KeyedDataFiles(str(tmp_path), "kernel-1.py311", ("stamp",))
    second = _KeyedDataFiles(str(tmp_path), "kernel-1.py311", ("stamp",))
    monkeypatch.setattr(_KeyedDataFiles, "_load_index", lambda self: {})  # both read it empty
    first.save(("sig", "f32"), b"f32 code")
    second.save(("sig", "f64"), b"f64 code")
    monkeypatch.undo()
    assert first.load(("sig", "f64")) == b"f64 code"
    assert first.load(("sig", "f32")) is None
    first.save(("sig", "f32"), b"f32 code")
    assert first.load(("sig", "f32")) == b"f32 code" and second.load(("sig", "f64")) == b"f64 code"


def test_callees_come_before_their_callers_and_inlined_kernels_are_looked_through():
    scaled = njit(nogil=True)(specialise(_scaled, FACTOR=2.0))
    plus_one = njit(nogil=True, inline="always")(specialise(_scaled_plus_one, scaled=scaled))
    kernel = njit(nogil=True)(specialise(_plus_one_inlined, plus_one=plus_one))
    assert list(_separate_callees(kernel.py_func, set())) == [scaled]
    outer = njit(nogil=True)(specialise(_plus_one_inlined, plus_one=kernel))
    assert list(_separate_callees(outer.py_func, set())) == [scaled, kernel]


_WARM_PROCESS = """
import sys
sys.path.insert(0, {tests!r})
from numba import float64
from test_jit_cache import _scaled, _scaled_plus_one
from tracer.jit import njit, specialise, load_callees_first
scaled = njit(cache=True, nogil=True)(specialise(_scaled, FACTOR=2.0))
kernel = njit(cache=True, nogil=True)(specialise(_scaled_plus_one, scaled=scaled))
load_callees_first(kernel)
kernel.compile((float64,))
print(kernel(1.5), sum(scaled.stats.cache_hits.values()), sum(scaled.stats.cache_misses.values()),
      sum(kernel.stats.cache_hits.values()))
"""


def test_a_process_that_finds_a_kernel_cached_loads_its_callees_own_code_first(tmp_path):
    """numba links a copy of each callee into its caller and optimises it again there; a call
    goes to the first definition loaded. The first process compiles the callee first; a later
    one, finding both cached, must load the callee's own code before the kernel (the bundle
    search's copy ran 8 % slower). Here: no callee loaded in the first process from the cache,
    its cached code loaded in the second, and the kernel's still right."""
    code = _WARM_PROCESS.format(tests=str(Path(__file__).parent))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                           timeout=300).stdout.split() for _ in range(2)]
    assert runs[0] == ["4.0", "0", "1", "0"]  # compiled: the kernel compiles its callee first
    assert runs[1] == ["4.0", "1", "0", "1"]  # from the cache: the callee's own code, then the kernel


def test_only_current_cache_entries_are_loaded_first(monkeypatch):
    """An entry under an old key (an edited module) is not loaded: it would be compiled instead."""
    from numba.core.registry import cpu_target
    scaled = njit(cache=True, nogil=True)(specialise(_scaled, FACTOR=5.0))
    scaled(1.0)
    codegen = cpu_target.target_context.codegen()
    assert [str(s) for s in scaled._cache.signatures(codegen)] == ["(float64,)"]
    index = scaled._cache._cache_file._load_index()
    stale = {(key[0], key[1], ("old", "key")): name for key, name in index.items()}
    monkeypatch.setattr(type(scaled._cache._cache_file), "_load_index", lambda self: stale)
    assert scaled._cache.signatures(codegen) == []
