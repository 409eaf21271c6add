"""Output paths checked before the work starts (a command that runs for minutes must not fail
at its end, or leave a traceback, because its output cannot be written), and written
atomically: under a temporary name in the same folder, then renamed, so that a signal or an
error never leaves a half-written file under the final name."""
from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator
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
    if folder.exists() and not folder.is_dir():
        raise UserError(f"{option} {text}: {folder} is a file, not a folder")
    if not folder.is_dir():
        raise UserError(f"{option} {text}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"{option} {text}: cannot write in {folder} (permission denied)")


def check_same_outputs(outputs: dict[str, str | Path | None]) -> None:
    """Refuse two options naming one file (``{option: path}``; None skipped): the second
    write would replace the first's output."""
    seen: dict[Path, str] = {}
    for option, path in outputs.items():
        if path is None:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise UserError(f"{seen[key]} and {option} name the same file {path}; give two names")
        seen[key] = option


def check_replaces_only(path: str | Path, option: str, kind: str,
                        is_kind: Callable[[Path], bool]) -> None:
    """Refuse to replace an existing file that is not ``kind``, what the command writes
    (``is_kind`` recognises one): re-running a command over its own output is fine, writing
    a model over a twin's truth file or a user's notes is not."""
    path = Path(path)
    if path.is_file() and not is_kind(path):
        raise UserError(f"{option} {path}: exists and is not {kind}; not replaced (give "
                        "another name, or remove it first)")


#: Larger than any JSON file delta6 writes: a bigger file is not one of them, unread.
MAX_OWN_JSON_BYTES = 16 << 20


def json_object(path: str | Path) -> dict | None:
    """The JSON object in ``path``, None if it is not one (or is too large to be ours)."""
    try:
        if Path(path).stat().st_size > MAX_OWN_JSON_BYTES:
            return None
        value = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def temporary_path(path: Path) -> Path:
    """Where ``path`` is written before its rename: the same folder (a rename is atomic only
    within one file system), a name of this process's own (two runs do not collide)."""
    return path.with_name(f"{path.name}.{os.getpid()}{PARTIAL_SUFFIX}")


@contextlib.contextmanager
def written_together(*paths: str | Path) -> Iterator[list[Path]]:
    """Yield a temporary name for each of ``paths``; the block writes them. When it ends
    normally they replace ``paths``; the last one is removed first and renamed last, so where
    it exists, its companions are those of the same run (a model JSON and its ONNX, a
    report's Markdown and its plots). On any exception (KeyboardInterrupt and the CLI's
    SIGTERM too) the temporaries are removed and the final names keep what they held. An
    OSError is one line naming the final file."""
    finals = [Path(p) for p in paths]
    temps = [temporary_path(p) for p in finals]
    current = finals[-1]
    try:
        try:
            yield temps
            current = finals[-1]
            if len(finals) > 1:
                finals[-1].unlink(missing_ok=True)
            for tmp, final in zip(temps, finals):
                current = final
                os.replace(tmp, final)
        except OSError as exc:
            # the file the error is about, by its final name (a temporary's means nothing)
            named = next((f for t, f in zip(temps, finals) if exc.filename in (t, str(t))),
                         current)
            raise UserError(f"cannot write {named}: {exc.strerror or exc}") from None
    finally:
        for tmp in temps:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)


def write_atomically(path: str | Path, produce: Callable[[Path], object]) -> Path:
    """``produce(tmp)`` writes the file, which then replaces ``path`` in one step."""
    with written_together(path) as (tmp,):
        produce(tmp)
    return Path(path)


def write_text_atomically(path: str | Path, text: str) -> Path:
    return write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
