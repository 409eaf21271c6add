"""One BLAS thread while the diagnosis runs.

The diagnosis multiplies many small matrices (solves of a few hundred unknowns, Gram updates of
a few thousand rows). On a machine whose cores are busy, OpenBLAS's thread pool spin-waits on
every such call: measured on two shared cores, a 150 x 150 solve took 25 ms with the pool and
0.5 ms without, a 120,000 x 150 Gram 6.8 s against 0.19 s. The pool is found in the process
(numpy's bundled OpenBLAS, whatever its symbol prefix) and set back when the diagnosis ends; on
a BLAS without that control nothing changes.
"""
from __future__ import annotations

import contextlib
import ctypes
import re

_PREFIXES = ("scipy_openblas_", "openblas_")
_SUFFIXES = ("64_", "")


def _controls():
    try:
        maps = open("/proc/self/maps", encoding="ascii", errors="replace").read()
    except OSError:
        return []
    found = []
    for path in sorted(set(re.findall(r"(/\S*openblas\S*\.so\S*)", maps))):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in _PREFIXES:
            for suffix in _SUFFIXES:
                get = getattr(lib, f"{prefix}get_num_threads{suffix}", None)
                put = getattr(lib, f"{prefix}set_num_threads{suffix}", None)
                if get is not None and put is not None:
                    put.argtypes = [ctypes.c_int]
                    found.append((get, put))
    return found


@contextlib.contextmanager
def one_thread():
    """Run the body with every loaded OpenBLAS limited to one thread."""
    controls = _controls()
    before = [get() for get, _ in controls]
    for _, put in controls:
        put(1)
    try:
        yield
    finally:
        for (_, put), n in zip(controls, before):
            put(n)
