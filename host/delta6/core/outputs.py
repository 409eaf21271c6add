"""Output paths checked before the work starts: a command that runs for minutes must not fail
at its end (or leave a traceback) because its output cannot be written."""
from __future__ import annotations

import os
from pathlib import Path

from delta6.core.errors import UserError
from delta6.core.paths import DESIGNS_DIR

PARTIAL_SUFFIX = ".partial"


def check_output_file(path: str | Path, option: str, *, force: bool = True,
                      partial: bool = False, inputs=()) -> Path:
    """``path`` as a file this command may create: not a directory, in a folder that exists
    and can be written, not one of the files the command reads (``inputs``; None entries are
    skipped) nor a shipped design. Without ``force`` an existing file is refused (a log is not
    regenerable); with ``partial`` so is the ``.partial`` file an interrupted run left."""
    text = str(path)
    path = Path(path)
    if text.endswith(("/", os.sep)) or path.is_dir():
        raise UserError(f"{option} {text}: is a folder; give a file name")
    _check_folder(path.parent, option, text)
    check_not_an_input(path, option, inputs)
    if not force:
        candidates = [path] + ([path.with_name(path.name + PARTIAL_SUFFIX)] if partial else [])
        for existing in candidates:
            if existing.exists():
                what = ("an interrupted run left it: keep what it holds by renaming it"
                        if existing is not path else "not replaced")
                raise UserError(f"{option} {existing} exists ({what}; --force replaces it)")
    elif path.exists() and not os.access(path, os.W_OK):
        raise UserError(f"{option} {text}: cannot be replaced (permission denied)")
    return path


def check_not_an_input(path: Path, option: str, inputs=()) -> None:
    """Refuse an output that is a file the command reads, or a design shipped with the
    package (a calibration written over delta6.toml replaced the design)."""
    if not path.exists():
        return
    for source in inputs:
        if source is not None and Path(source).exists() and _same(path, Path(source)):
            raise UserError(f"{option} {path}: is the input {source} (it would be overwritten)")
    if path.resolve().parent == DESIGNS_DIR.resolve():
        raise UserError(f"{option} {path}: is a design shipped with delta6 (write elsewhere)")


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def check_output_folder(path: str | Path, option: str) -> Path:
    """``path`` as a folder this command writes into (created if missing)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f"{option} {path}: exists and is not a folder")
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK):
            raise UserError(f"{option} {path}: cannot write in this folder (permission denied)")
        return path
    _check_folder(path.parent, option, str(path))
    return path


def _check_folder(folder: Path, option: str, text: str) -> None:
    folder = folder if str(folder) else Path(".")
    if not folder.is_dir():
        raise UserError(f"{option} {text}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"{option} {text}: cannot write in {folder} (permission denied)")
