"""The kernel cache (tracer/jit.py): specialised kernels keep machine code of their own across
processes, and concurrent saves never make one entry name another's code."""
from __future__ import annotations

import itertools
import subprocess
import sys

import numba
import pytest
from numba.core import bytecode

from tracer.jit import _KeyedDataFiles, njit, specialise
from tracer.variants import Variant

pytestmark = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="compiles kernels")


def _scaled(x):
    return x * FACTOR  # noqa: F821 (specialise's)


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
