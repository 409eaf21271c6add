"""Build firmware sources natively (host g++) into shared libraries for ctypes-driven tests.

The builder lives in :mod:`delta6.nativebuild` (the simulated device uses it too); this module
keeps the names the tests import.
"""
from delta6.nativebuild import BASE_FLAGS, BUILD, CXX, ROOT, build_library, load_library  # noqa: F401
