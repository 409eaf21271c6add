"""``delta6 codegen``: write the firmware's design header (optionally build the AVR image), or
with ``--wire`` the core's wire layout header."""
from __future__ import annotations

import argparse
import functools
import re
import shlex
import sys
from pathlib import Path
from typing import NamedTuple

from delta6.build import avrbuild
from delta6.core import calibration as calibration_mod
from delta6.core import design as design_mod
from delta6.core import paths, residualmodel
from delta6.core.errors import UserError
from delta6.core.outputs import check_not_an_input, write_text_atomically
from delta6.core.workspace import load_checked
from delta6.link.protocol import VERSION as PROTOCOL_VERSION
from delta6_codegen.design_header import GENERATED_MARKER
from delta6_codegen.wire_header import HEADER_RELPATH as WIRE_HEADER_RELPATH

NAME = "codegen"
HELP = ("write the firmware header generated/delta6_design.h for a design, and with "
        "--calibration a unit's generated/delta6_calibration.h and with --model an on-chip "
        "residual's generated/delta6_model.h next to it "
        "(--build: into build/designs/NAME/, NAME-cal-HASH for a calibrated unit and "
        "+MODEL-HASH with a model, and build the ATmega328P firmware image there), "
        "or with --wire the protocol's generated/delta6_wire.h")
HEADER_RELPATH = Path("generated") / "delta6_design.h"
CALIBRATION_HEADER = "delta6_calibration.h"
COMMITTED_HEADER = avrbuild.COMMITTED_DESIGN_INCLUDE / HEADER_RELPATH
WIRE_RELPATH = Path(WIRE_HEADER_RELPATH)
MODEL_HEADER = "delta6_model.h"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("design", metavar="DESIGN.toml", type=Path, nargs="?",
                        help="design file (not with --wire)")
    parser.add_argument("--wire", action="store_true",
                        help=f"write the wire layout header {WIRE_RELPATH} from the protocol "
                             "tables of delta6.link.protocol instead of a design header")
    parser.add_argument("-o", "--output", metavar="PATH", type=Path,
                        help=f"header to write (default: {_rel(COMMITTED_HEADER)}, the one the "
                             "PlatformIO build uses; with --build: "
                             "build/designs/NAME/include/generated/delta6_design.h, NAME as "
                             "above; with --wire: "
                             f"{WIRE_RELPATH})")
    parser.add_argument("--build", action="store_true",
                        help="also build the ATmega328P firmware application for this design "
                             "with the local avr-gcc (the committed header is left alone)")
    parser.add_argument("--calibration", metavar="CAL.toml", type=Path,
                        help="compile a unit's calibration (delta6 calibrate) into the firmware: "
                             f"writes {CALIBRATION_HEADER} next to the design header; without "
                             "it, a calibration header codegen wrote there is removed (another "
                             "file there is refused)")
    parser.add_argument("--model", metavar="MODEL.json", type=Path,
                        help="compile an on-chip residual model (delta6 train --target mcu) into "
                             f"the firmware: writes {MODEL_HEADER} next to the design header; "
                             "without it, a model header codegen wrote there is removed")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 if the header differs from what the design "
                             "(or with --wire, the protocol) generates")
    add_allow_implausible(parser)


ALLOW_IMPLAUSIBLE = "--allow-implausible"


def add_allow_implausible(parser: argparse.ArgumentParser) -> None:
    """The override of :func:`firmware_notes`, for every command that builds a firmware."""
    parser.add_argument(ALLOW_IMPLAUSIBLE, action="store_true",
                        help="build the firmware even for a design with a length outside 1..2000 "
                             "mm or a spring rate outside 0.001..100 N*m/rad (refused "
                             "otherwise: such a value is usually written in another unit)")


def firmware_notes(design: design_mod.Design, allow_implausible: bool = False) -> list[str]:
    """The checks run before any file is written for a design's firmware (codegen, flash,
    virtual): a value that reads as another unit is refused, as its firmware would run and
    report nonsense; returns the notes to print (the wire's lost steps; the unit slips when
    allowed)."""
    slips = design_mod.unit_slips(design)
    if slips and not allow_implausible:
        more = f" (and {len(slips) - 1} more)" if len(slips) > 1 else ""
        raise UserError(f"design {design.name}: {slips[0]}{more}: no firmware is built for it; "
                        f"fix the unit, or pass {ALLOW_IMPLAUSIBLE} if the value is meant")
    notes = design_mod.unit_slip_notes(design) + [resolution_note(design)]
    return [note for note in notes if note]


def source_label(path: Path) -> str:
    """How the banners and commands name a file: relative to the repository when inside it
    (the bytes do not depend on the working directory), else its absolute path (a command in
    a banner runs from anywhere)."""
    resolved = path.resolve()
    shipped = paths.DESIGNS_DIR.resolve()
    if resolved.parent == shipped:      # a shipped design, however it was reached
        return f"designs/{resolved.name}"
    try:
        return resolved.relative_to(paths.REPO_ROOT.resolve()).as_posix()
    except ValueError:
        return resolved.as_posix()


def codegen_command(design_path: Path, cal_path: Path | None = None,
                    model_path: Path | None = None, *extra: str) -> str:
    """The ``delta6 codegen`` command line that writes these headers (``extra``: its other
    arguments), for the banners and for --check's hint."""
    words = ["delta6", NAME, source_label(design_path)]
    for flag, path in (("--calibration", cal_path), ("--model", model_path)):
        if path is not None:
            words += [flag, source_label(path)]
    return shlex.join(words + list(extra))


def header_text(path: Path, command: str | None = None) -> tuple[design_mod.Design, str]:
    from delta6_codegen import render
    design = load_checked(path)
    return design, render(design, source_label(path), command=command)


def calibration_text(design: design_mod.Design, design_path: Path, cal_path: Path | None,
                     command: str | None = None):
    """The calibration header for ``cal_path`` (None: no calibration, no header)."""
    if cal_path is None:
        return None, None
    from delta6_codegen import render_calibration
    cal = calibration_mod.load(cal_path)
    cal.check_design(design)
    return cal, render_calibration(design, cal, source_label(design_path), source_label(cal_path),
                                   command=command)


#: Re-exported: the cost limits live with the model file (evaluate and train check them too).
MAX_MODEL_MACS = residualmodel.MAX_MODEL_MACS


def model_text(design: design_mod.Design, design_path: Path, model_path: Path | None, cal=None,
               command: str | None = None):
    """The model header for ``model_path`` (None: no model, no header); refuses a model
    trained for another design or over another base than the one this firmware computes, and
    one too costly for the board's rated rate."""
    if model_path is None:
        return None, None
    from delta6_codegen import render_model
    model = residualmodel.load(model_path)
    residualmodel.check_base(model, design, cal)
    residualmodel.check_cost(model.net.macs, design, cal, str(model_path))
    return model, render_model(model, source_label(design_path), source_label(model_path),
                               command=command)


class Headers(NamedTuple):
    """A design's header and, if given, a calibration's and a model's, checked together."""

    design: design_mod.Design
    text: str
    cal: calibration_mod.Calibration | None
    cal_text: str | None
    model: residualmodel.ResidualModel | None
    model_text: str | None


def generate_headers(design_path: Path, cal_path: Path | None = None,
                     model_path: Path | None = None, allow_implausible: bool = False,
                     command: str | None = None, design_command: str | None = None) -> Headers:
    """Everything ``delta6 codegen`` (and ``delta6 flash``, ``delta6 virtual``) writes for a
    firmware: refuses a design in another unit (:func:`firmware_notes`, whose notes it prints),
    a calibration of another design and a model over another base. ``command``: the command
    line the calibration's and model's banners name (default: :func:`codegen_command`);
    ``design_command``: the design header's, which names no calibration or model (its bytes
    are the same for all of them, so flashing a calibrated shipped design leaves the committed
    header as it is; default: ``delta6 codegen DESIGN``)."""
    command = command or codegen_command(design_path, cal_path, model_path)
    design, text = header_text(design_path, design_command or codegen_command(design_path))
    for note in firmware_notes(design, allow_implausible):
        print(note, file=sys.stderr)
    cal, cal_text = calibration_text(design, design_path, cal_path, command)
    model, model_text_ = model_text(design, design_path, model_path, cal, command)
    return Headers(design, text, cal, cal_text, model, model_text_)


def write_headers(out: Path, headers: Headers) -> list[str]:
    """Write the design header to ``out`` and the calibration and model headers next to it,
    removing those the firmware must not carry (a header left from an earlier build would be
    compiled in). Returns one line per file, saying what was done."""
    design, cal, model = headers.design, headers.cal, headers.model
    cal_out, model_out = out.with_name(CALIBRATION_HEADER), out.with_name(MODEL_HEADER)
    for path in (out, cal_out, model_out):      # all before the first write
        check_generated(path)
    lines = [_write_line(out, headers.text, f"design '{design.name}' (hash 0x{design.hash32():08x})")]
    if cal is not None:
        lines.append(_write_line(cal_out, headers.cal_text,
                                 f"calibration '{cal.name}' (hash 0x{cal.hash32():08x})"))
    elif _remove(cal_out):
        lines.append(f"removed {_rel(cal_out)}: the firmware is the uncalibrated one")
    if model is not None:
        lines.append(_write_line(model_out, headers.model_text,
                                 f"model '{model.name}' (hash 0x{model.hash32():08x}, "
                                 f"{model.net.macs} multiply-accumulates per sample)"))
    elif _remove(model_out):
        lines.append(f"removed {_rel(model_out)}: no model")
    return lines


def check_companion_names(out: Path, option: str = "-o") -> None:
    """Refuse a design header named as a companion: written there, the design header was
    then removed as a stale calibration header, or replaced by the calibration's."""
    if out.name in (CALIBRATION_HEADER, MODEL_HEADER):
        raise UserError(f"{option} {out}: {out.name} is the name of the header written next to "
                        f"the design header; name the design header otherwise "
                        f"({HEADER_RELPATH.name})")


def is_generated(path: Path) -> bool:
    """Whether ``path`` starts with the line every header codegen writes starts with."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(GENERATED_MARKER.encode()))
    except OSError:
        return True     # cannot tell: writing or removing it says what is wrong
    return head == GENERATED_MARKER.encode()


def check_generated(path: Path) -> None:
    """Refuse to replace or remove a header codegen did not write (a hand-written one): next
    to the design header the firmware would compile it in, so it is not left alone silently
    either."""
    if path.is_file() and not is_generated(path):
        raise UserError(f"{_rel(path)}: not a header delta6 codegen wrote (its first line is "
                        f"not '{GENERATED_MARKER}'): neither replaced nor removed; move it "
                        "away, or write the headers to another folder (-o)")


def _write_line(path: Path, text: str, what: str) -> str:
    verb = "wrote" if _write_if_changed(path, text) else "unchanged:"
    return f"{verb} {_rel(path)} for {what}"


def build_name(design: design_mod.Design, cal=None, model=None) -> str:
    """The build directory's name: one per design, per calibrated unit and per model. A
    model's name is a label (any printable ASCII): only its letters, digits, '.', '-' and
    '_' reach the folder's name, which is one path component whatever the label."""
    name = design.name if cal is None else f"{design.name}-cal-{cal.hash32():08x}"
    if model is not None:
        name += f"+{re.sub(r'[^A-Za-z0-9._-]', '_', model.name)}-{model.hash32():08x}"
    return name


def output_path(args: argparse.Namespace, design: design_mod.Design, cal=None,
                model=None) -> Path:
    if args.output is not None:
        return args.output
    if args.build:
        return avrbuild.design_include_dir(build_name(design, cal, model)) / HEADER_RELPATH
    return COMMITTED_HEADER


def include_dir_of(header: Path) -> Path:
    """The directory to put on the include path so that "generated/delta6_design.h" is
    ``header``."""
    header = header.resolve()
    if header.name != HEADER_RELPATH.name or header.parent.name != HEADER_RELPATH.parent.name:
        raise UserError(f"--build needs the header at .../{HEADER_RELPATH.as_posix()} "
                        f"(got {header})")
    return header.parent.parent


def run(args: argparse.Namespace) -> int:
    if args.wire:
        return run_wire(args)
    if args.design is None:
        raise UserError("give a design file (delta6 codegen designs/delta6.toml) or --wire")
    if args.build or args.output is None:
        paths.checkout()    # the firmware tree the header belongs to, or one line saying so
    if args.output is not None:
        check_companion_names(args.output)
    extra = rerun_extra(args)
    command = codegen_command(args.design, args.calibration, args.model, *extra)
    headers = generate_headers(args.design, args.calibration, args.model, args.allow_implausible,
                               command, codegen_command(args.design, None, None, *extra))
    out = output_path(args, headers.design, headers.cal, headers.model)
    if args.output is not None:      # (its folder is made: generated/ next to the firmware)
        check_not_an_input(out, "-o", [args.design, args.calibration, args.model])
    if args.build:
        include_dir_of(out)     # a usage error: said before any header is written
    if args.check:
        return _check(args, out, headers.text, {out.with_name(CALIBRATION_HEADER): headers.cal_text,
                                                out.with_name(MODEL_HEADER): headers.model_text},
                      command)
    for line in write_headers(out, headers):
        print(line)
    design, cal, model = headers.design, headers.cal, headers.model
    if args.build:
        image = build_image(design, include_dir_of(out), cal, model)
        sizes = image.sizes
        print(f"built {_rel(image.elf)} and .hex ({image.mcu}): flash {sizes.flash} B of "
              f"{avrbuild.NANO.flash_bytes}, static RAM {sizes.ram} B of {avrbuild.NANO.ram_bytes}"
              + avrbuild.flash_note(sizes.flash))
    return 0


@functools.lru_cache(maxsize=16)
def _resolution(design):
    """The box search takes about a second: once per design in a process."""
    from delta6.link.wirescale import resolution_check
    return resolution_check(design)


def resolution_note(design) -> str | None:
    """A line when the wire's LSB is coarser than one encoder count's smallest step somewhere
    in the joint box (docs/protocol.md, "One encoder count is never lost"): the design works,
    but the stream drops such steps."""
    r = _resolution(design)
    lost = [f"{what} (margin {margin:.2f})" for what, margin in
            (("a force step of joints 1..3", r.force_margin),
             ("a moment step of joints 4..6", r.moment_margin)) if margin < 1.0]
    if not lost:
        return None
    return (f"note: design {design.name}: one encoder count can change the wrench by less "
            f"than one wire LSB somewhere in the joint box: {', '.join(lost)}; the stream "
            "loses such steps (docs/protocol.md, section 7)")


def run_wire(args: argparse.Namespace) -> int:
    """``--wire``: the core's generated/delta6_wire.h from delta6.link.protocol."""
    from delta6_codegen.wire_header import COMMAND, render_wire
    if (args.design is not None or args.build or args.calibration is not None
            or args.model is not None):
        raise UserError("--wire takes no design file, --calibration, --model or --build: the "
                        "wire layout is the same for every design")
    out = args.output if args.output is not None else paths.checkout() / WIRE_RELPATH
    text = render_wire()
    if args.check:
        return check(out, text, "delta6.link.protocol", COMMAND)
    check_generated(out)
    verb = "wrote" if _write_if_changed(out, text) else "unchanged:"
    print(f"{verb} {_rel(out)} (wire protocol {'.'.join(map(str, PROTOCOL_VERSION))})")
    return 0


def rerun_extra(args: argparse.Namespace) -> list[str]:
    """The arguments of ``delta6 codegen`` beyond its files that a user re-runs it with
    (without --check): where the headers go, and the override."""
    extra = []
    if args.output is not None and args.output.resolve() != COMMITTED_HEADER.resolve():
        extra += ["-o", source_label(args.output)]
    extra += [flag for flag, given in (("--build", args.build),
                                       (ALLOW_IMPLAUSIBLE, args.allow_implausible)) if given]
    return extra


def check(out: Path, text: str, source: str, command: str) -> int:
    """``--check``: 0 if ``out`` holds ``text``, else 1 with the command that fixes it."""
    if _read(out) != text:
        print(_stale(out, text, source, command), file=sys.stderr)
        return 1
    print(f"{_rel(out)} is up to date")
    return 0


def _stale(path: Path, wanted: str | None, source: str, command: str) -> str:
    """What is wrong with a header that does not hold ``wanted`` (None: must not exist)."""
    if wanted is None:
        state = f"should not exist for {source}"
    elif not path.exists():
        state = "is missing"
    else:
        state = f"is out of date with {source}"
    return f"{_rel(path)} {state}; run: {command}"


def _check(args, out: Path, text: str, extra: dict, command: str) -> int:
    """``--check`` of the design header and of the calibration and model headers (or their
    absence)."""
    label = source_label(args.design)
    status = check(out, text, label, command)
    for path, wanted in extra.items():
        if _read(path) != wanted:
            print(_stale(path, wanted, label, command), file=sys.stderr)
            status = 1
    return status


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None


def _remove(path: Path) -> bool:
    """Remove ``path`` if it exists (a generated header: :func:`check_generated` refused any
    other before the first write); returns whether it did."""
    try:
        path.unlink()
    except FileNotFoundError:
        return False
    except OSError as exc:
        raise UserError(f"cannot remove {path}: {exc.strerror}") from None
    return True


def build_image(design: design_mod.Design, include_dir: Path, cal=None,
                model=None, defines=()) -> avrbuild.Image:
    """The firmware application for ``design`` (headers under ``include_dir``), in
    build/designs/NAME/atmega328p/ (NAME-cal-HASH for a calibrated unit, +MODEL-HASH with a
    model; ``defines``, for benchmarks, build into atmega328p-defines/)."""
    from delta6.build.appbuild import build_app
    name = build_name(design, cal, model)
    folder = "atmega328p-defines" if defines else "atmega328p"
    return build_app(include_dir, name=f"delta6-{name}", defines=list(defines),
                     out_dir=avrbuild.design_build_dir(name) / folder)


def design_firmware(path: Path, calibration: Path | None = None,
                    model_path: Path | None = None, defines=(),
                    allow_implausible: bool = False) -> avrbuild.Image:
    """Generate ``path``'s header (and ``calibration``'s and ``model_path``'s) into
    build/designs/NAME/include/ (the committed headers are left alone) and build the
    application for it: what ``delta6 virtual --design [--calibration] [--model]`` runs."""
    extra = ["--build"] + ([ALLOW_IMPLAUSIBLE] if allow_implausible else [])
    headers = generate_headers(path, calibration, model_path, allow_implausible,
                               codegen_command(path, calibration, model_path, *extra),
                               codegen_command(path, None, None, *extra))
    design, cal, model = headers.design, headers.cal, headers.model
    header = avrbuild.design_include_dir(build_name(design, cal, model)) / HEADER_RELPATH
    write_headers(header, headers)
    return build_image(design, include_dir_of(header), cal, model, defines)


def _write_if_changed(path: Path, text: str) -> bool:
    """Write ``text`` unless the file already holds it (its timestamp then stays, so builds
    do not redo work). Returns whether it wrote."""
    try:
        if path.read_text(encoding="utf-8") == text:
            return False
    except (OSError, UnicodeDecodeError):
        pass  # missing or unreadable: writing it says what is wrong, if anything
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None
    write_text_atomically(path, text)
    return True


def _rel(path: Path) -> str:
    try:
        return path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return str(path)
