"""Named random streams: every part of a run (trajectory, temperature, noise, each effect)
draws from its own stream keyed by the seed and its name, so adding or removing one part
changes nothing else of a run."""
from __future__ import annotations

import zlib

import numpy as np


def stream(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng([int(seed), zlib.crc32(name.encode())])
