"""Every ``delta6 COMMAND --option`` the README and docs/ quote names a command and options
that exist: a renamed or removed option fails here, not in a user's terminal."""
from __future__ import annotations

import argparse
import re

from delta6.cli import build_parser

from conftest import ROOT

COMMAND = re.compile(r"(?:^|`)(delta6 [a-z]+[^`\n]*)", re.M)
OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)")


def subcommands() -> dict[str, set[str]]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {s for a in sub._actions for s in a.option_strings}
            for name, sub in action.choices.items()}


def quoted_commands():
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for line in COMMAND.findall(path.read_text()):
            yield path.name, line.split("#")[0].split("|")[0]


def test_documented_commands_and_options_exist():
    known = subcommands()
    seen, wrong = 0, []
    for name, line in quoted_commands():
        command = line.split()[1]
        if command not in known:
            wrong.append(f"{name}: no command {command!r}: {line}")
            continue
        seen += 1
        wrong += [f"{name}: {command} has no {option}: {line}"
                  for option in OPTION.findall(line) if option not in known[command]]
    assert seen > 100 and not wrong, "\n".join(wrong)
