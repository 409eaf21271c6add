"""Where things are: the package's own data, and the source checkout the firmware tools need.

The model, the twin and the diagnosis need nothing but the installed package (the shipped
designs are package data). Building firmware, the natively compiled core and the virtual board
need the firmware and tool sources, which only a checkout of the repository has;
:func:`checkout` says so in one line when the package runs from an installed copy.
"""
from __future__ import annotations

from pathlib import Path

from delta6.core.errors import UserError

PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: The shipped design variants (``designs/`` at the top of a checkout points here).
DESIGNS_DIR = PACKAGE_DIR / "designs"
#: The design the tools use when none is given: the paper's Delta6.
DEFAULT_DESIGN = DESIGNS_DIR / "delta6.toml"

#: Where the checkout's root is when the package runs from one (host/delta6 is two levels
#: down); in an installed copy this path has no firmware, and :func:`checkout` says so.
REPO_ROOT = PACKAGE_DIR.parents[1]


def in_checkout() -> bool:
    return (REPO_ROOT / "firmware" / "lib").is_dir() and (REPO_ROOT / "tools").is_dir()


def checkout() -> Path:
    """The repository root; a one-line :class:`UserError` when running from an installed copy."""
    if not in_checkout():
        raise UserError("this command builds firmware or the virtual board and needs a source "
                        "checkout of delta6 (git clone, then tools/bootstrap.sh); the installed "
                        f"package at {PACKAGE_DIR} has no firmware sources")
    return REPO_ROOT


def build_dir(*parts: str) -> Path:
    """A folder under the checkout's ``build/`` (created by the caller)."""
    return checkout().joinpath("build", *parts)
