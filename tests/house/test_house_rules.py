"""The house rules of docs/architecture.md, checked: layers, no import cycle, lint, one version,
and the package installs and runs outside a checkout."""
from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import grimp
import pytest

import delta6

from conftest import ROOT

BIN = Path(sys.executable).parent


def _run(*cmd: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, **kw)


def test_the_layers_contract_holds():
    proc = _run(str(BIN / "lint-imports"), "--no-cache")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]


def test_ruff_finds_nothing():
    proc = _run(str(BIN / "ruff"), "check", "host", "codegen", "tests", "tools")
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-1000:]


def _cycles(graph, modules) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan's algorithm)."""
    edges = {m: sorted(graph.find_modules_directly_imported_by(m) & modules) for m in modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in edges[node]:
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while not component or component[-1] != node:
                component.append(stack.pop())
            if len(component) > 1:
                out.append(sorted(component))

    for root in sorted(modules):
        if root not in index:
            visit(root)
    return out


def test_no_import_cycle_between_modules():
    graph = grimp.build_graph("delta6", "delta6_codegen", cache_dir=None)
    # A package's __init__ re-exporting its modules is not a cycle of meaning; modules are.
    modules = {m for m in graph.modules if not graph.find_children(m)}
    assert _cycles(graph, modules) == []


def test_the_cycle_finder_finds_a_cycle():
    class G:
        def find_modules_directly_imported_by(self, m):
            return {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}[m]
    assert _cycles(G(), {"a", "b", "c", "d"}) == [["a", "b", "c"]]


def test_the_version_is_written_once():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" not in project and "version" in project["dynamic"]
    from importlib.metadata import version
    assert version("delta6") == delta6.__version__


@pytest.mark.slow
def test_a_non_editable_install_runs_the_analysis_commands(tmp_path):
    """pip install . (not editable) into a fresh venv whose dependencies come from this one,
    then the commands that need no firmware sources run with the default design from an
    unrelated directory, and one that needs them says so in one line."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    py = venv / "bin" / "python"
    # The outer venv's site-packages provide numpy & co; hide its editable delta6.
    env = {**os.environ, "PYTHONNOUSERSITE": "1"}
    site = subprocess.run([sys.executable, "-c", "import site; print(site.getsitepackages()[0])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    pth = next((venv / "lib").glob("python*/site-packages"))
    (pth / "outer.pth").write_text(site + "\n")
    proc = subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps",
                           str(ROOT)], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    work = tmp_path / "elsewhere"
    work.mkdir()
    delta6_bin = venv / "bin" / "delta6"
    where = subprocess.run([str(py), "-c", "import delta6; print(delta6.__file__)"], cwd=work,
                           capture_output=True, text=True, env=env)
    assert str(venv) in where.stdout, where.stdout + where.stderr   # the installed copy, not the checkout

    def cli(*args):
        return subprocess.run([str(delta6_bin), *args], cwd=work, capture_output=True, text=True, env=env)

    design = cli("design")
    assert design.returncode == 0 and "Fz" in design.stdout, design.stderr
    sim = cli("simulate", "--scenario", "paper", "--duration", "60", "-o", "run.csv")
    assert sim.returncode == 0, sim.stderr
    diag = cli("diagnose", "run.csv", "--json", "out.json")
    assert diag.returncode == 0, diag.stderr
    assert (work / "out.json").stat().st_size > 0
    # What needs the firmware sources says so in one line, exit 2.
    shipped = subprocess.run([str(py), "-c", "from delta6.core.paths import DEFAULT_DESIGN as d; print(d)"],
                             cwd=work, capture_output=True, text=True, env=env).stdout.strip()
    for needs_sources in [("codegen", shipped, "--build"), ("codegen", "--wire"),
                          ("info", "--port", "delta6sim://")]:
        proc = cli(*needs_sources)
        assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
        assert "checkout" in proc.stderr, proc.stderr
