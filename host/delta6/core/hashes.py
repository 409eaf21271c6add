"""32-bit hashes as files write them: hexadecimal text ("0x535534af")."""
from __future__ import annotations


def parse_hash32(value) -> int:
    """The number a 32-bit hash written as hexadecimal text stands for (compared as a number:
    the case of its digits does not matter). Raises ValueError saying what is wrong."""
    if not isinstance(value, str):
        raise ValueError('must be a hex string like "0x535534af"')
    try:
        number = int(value, 16)
    except ValueError:
        raise ValueError(f"is not a hexadecimal hash: {value[:40]!r}") from None
    if not 0 <= number < 2**32:
        raise ValueError("does not fit 32 bits")
    return number
