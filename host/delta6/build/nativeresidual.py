"""The residual engine (firmware/lib/delta6_core/src/delta6_residual.cpp) compiled natively and
driven through ctypes (shim: firmware/native/residual_shim.cpp), for the cross-checks against
the numpy reference :mod:`delta6.core.int8net`.

A :class:`NativeResidual` is one network with its state on the C side: feed it a stream in
pieces and it carries the history between calls, as the board does.
"""
from __future__ import annotations

import ctypes

import numpy as np

from delta6.build.nativebuild import FIRMWARE_CORE, FIRMWARE_NATIVE, load_library
from delta6.core.int8net import FEATURE_KINDS, Int8Net

SOURCES = [FIRMWARE_CORE / "delta6_residual.cpp", FIRMWARE_NATIVE / "residual_shim.cpp"]
_P = ctypes.c_void_p


def library(include_dir=None) -> ctypes.CDLL:
    """The shim; with ``include_dir`` (holding generated/delta6_model.h) it also offers a
    session on that header's model (:meth:`NativeResidual.generated`)."""
    if include_dir is None:
        lib = load_library("residual_shim", SOURCES, include_dirs=[FIRMWARE_CORE])
    else:
        lib = load_library("residual_shim_generated", SOURCES,
                           include_dirs=[FIRMWARE_CORE, include_dir], flags=("-DD6R_GENERATED",))
        lib.d6r_create_generated.restype = _P
        lib.d6r_create_generated.argtypes = [ctypes.c_uint16]
        lib.d6r_generated_hash.restype = ctypes.c_uint32
    lib.d6r_requantize16.restype = ctypes.c_int32
    lib.d6r_requantize16.argtypes = [ctypes.c_int16, ctypes.c_int16, ctypes.c_uint8]
    lib.d6r_requantize32.restype = ctypes.c_int32
    lib.d6r_requantize32.argtypes = [ctypes.c_int32, ctypes.c_int16, ctypes.c_uint8]
    lib.d6r_create.restype = _P
    lib.d6r_create.argtypes = [ctypes.c_uint16, ctypes.c_uint8, _P, _P, _P, _P, ctypes.c_uint8,
                               _P, _P, _P, _P, _P, _P, _P, _P, ctypes.c_uint8, ctypes.c_uint16]
    lib.d6r_destroy.argtypes = [_P]
    lib.d6r_stride.restype = ctypes.c_uint8
    lib.d6r_stride.argtypes = [_P]
    lib.d6r_feed.argtypes = [_P, ctypes.c_size_t, _P, _P, _P, _P]
    lib.d6r_quantize_input.argtypes = [_P, ctypes.c_size_t, _P, _P]
    lib.d6r_apply_output.argtypes = [_P, ctypes.c_size_t, _P, _P]
    return lib


def _buf(values, dtype) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(values, dtype=dtype).reshape(-1))


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_P)


class NativeResidual:
    """``net`` on the C engine at ``board_rate_hz``; use as a context manager or call close()."""

    def __init__(self, net: Int8Net, board_rate_hz: int = 0, lib: ctypes.CDLL | None = None,
                 generated: bool = False):
        self.lib = lib or library()
        self.net = net
        if generated:   # the model compiled into ``lib`` from its header
            board = int(board_rate_hz) if board_rate_hz else int(round(net.rate_hz))
            self.handle = self.lib.d6r_create_generated(board)
            return
        rate = int(round(net.rate_hz))
        board = int(board_rate_hz) if board_rate_hz else rate
        f = net.features
        self._keep = [
            _buf([FEATURE_KINDS[x.kind] for x in f], np.uint8), _buf([x.param for x in f], np.int16),
            _buf([x.multiplier for x in f], np.int16), _buf([x.shift for x in f], np.uint8),
            _buf([net.inputs] + [layer.shape[0] for layer in net.layers], np.uint8),
            _buf([layer.relu for layer in net.layers], np.uint8),
            _buf(np.concatenate([layer.weights.reshape(-1) for layer in net.layers]), np.int8),
            _buf(np.concatenate([layer.bias for layer in net.layers]), np.int32),
            _buf(np.concatenate([layer.multiplier for layer in net.layers]), np.int16),
            _buf(np.concatenate([layer.shift for layer in net.layers]), np.uint8),
            _buf(net.input_scale, np.float32), _buf(net.output_step, np.float32),
        ]
        k = self._keep
        self.handle = self.lib.d6r_create(rate, len(f), *map(_ptr, k[:4]), len(net.layers),
                                          *map(_ptr, k[4:]), net.history_length(), board)
        if not self.handle:
            raise ValueError("the network is too large for the test shim")

    @property
    def stride(self) -> int:
        return int(self.lib.d6r_stride(self.handle))

    def feed(self, base, counts, valid=None) -> np.ndarray:
        """Corrections (n, 6) int16 for the next n samples."""
        b, c = _buf(base, np.int16), _buf(counts, np.int16)
        n = len(b) // 6
        v = _buf(np.ones(n) if valid is None else valid, np.uint8)
        out = np.zeros(6 * n, dtype=np.int16)
        self.lib.d6r_feed(self.handle, n, _ptr(b), _ptr(c), _ptr(v), _ptr(out))
        return out.reshape(n, 6)

    def quantize_input(self, wrench) -> np.ndarray:
        w = _buf(wrench, np.float32)
        out = np.zeros(len(w), dtype=np.int16)
        self.lib.d6r_quantize_input(self.handle, len(w) // 6, _ptr(w), _ptr(out))
        return out.reshape(-1, 6)

    def apply_output(self, correction, wrench) -> np.ndarray:
        c, w = _buf(correction, np.int16), _buf(wrench, np.float32).copy()
        self.lib.d6r_apply_output(self.handle, len(c) // 6, _ptr(c), _ptr(w))
        return w.reshape(-1, 6)

    def close(self) -> None:
        if self.handle:
            self.lib.d6r_destroy(self.handle)
            self.handle = None

    def __enter__(self) -> "NativeResidual":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
