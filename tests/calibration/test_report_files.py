"""The calibration report's files: written under temporary names and renamed together, the
Markdown last, so a stop signal midway leaves no partial report (and no half-written file)."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from delta6.calibration import report
from delta6.cli import main
from delta6.core.calibration import neutral
from delta6.core.design import load
from delta6.link.logfile import read_log

from conftest import DESIGNS

DESIGN = load(DESIGNS / "delta6.toml")
TABLE = {"p95_pct": [1.0] * 6, "p99_pct": [2.0] * 6, "max_pct": [3.0] * 6}


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    path = tmp_path_factory.mktemp("report") / "run.csv"
    assert main(["simulate", "--duration", "4", "--seed", "2", "-o", str(path)]) == 0
    return read_log(path)


def _fit():
    return SimpleNamespace(calibration=neutral(DESIGN), diagnosis=None, chosen_by="--effect",
                           heldout_before=TABLE, heldout_after=TABLE, heldout_before_rig=None,
                           heldout_after_rig=None, seconds=1.0, latency_s=0.0,
                           latency_given=True, notes=[])


def test_the_report_is_written_whole(tmp_path, log):
    path = report.write_report(_fit(), log, DESIGN, tmp_path / "rep")
    names = sorted(p.name for p in (tmp_path / "rep").iterdir())
    assert names == sorted([report.MARKDOWN, report.HELDOUT_PLOT, report.RESIDUAL_PLOT])
    text = path.read_text()
    assert f"({report.HELDOUT_PLOT})" in text and f"({report.RESIDUAL_PLOT})" in text
    assert (tmp_path / "rep" / report.RESIDUAL_PLOT).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("earlier", [False, True])
def test_an_interrupted_report_leaves_no_partial_files(tmp_path, log, monkeypatch, earlier):
    """Interrupted while its second plot is written: no file of this run under a final name,
    and no calibration.md of an earlier run beside plots it does not describe."""
    from matplotlib.figure import Figure
    out = tmp_path / "rep"
    if earlier:
        report.write_report(_fit(), log, DESIGN, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()} if earlier else {}
    real, calls = Figure.savefig, []

    def savefig(self, fname, **kw):
        calls.append(fname)
        if len(calls) == 2:
            with open(fname, "wb") as f:
                f.write(b"\x89PNG half")
            raise KeyboardInterrupt
        real(self, fname, **kw)

    monkeypatch.setattr(Figure, "savefig", savefig)
    with pytest.raises(KeyboardInterrupt):
        report.write_report(_fit(), log, DESIGN, out)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
