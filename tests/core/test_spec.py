"""The design report against the paper's Tables II and III, and the converged limits."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from delta6.cli import main
from delta6.core import spec
from delta6.core.design import load

from conftest import DESIGNS

# Table III: ID -> (file, |Fmax| N, |Mmax| N*m, Fres N, Mres N*m), as printed.
TABLE_III = {
    0: ("delta6.toml", 25.10, 0.580, 0.01187, 0.00031),
    1: ("half-scale.toml", 50.21, 0.580, 0.02375, 0.00031),
    2: ("stiff.toml", 37.65, 0.870, 0.01781, 0.00046),
    3: ("half-scale-stiff.toml", 75.31, 0.870, 0.03562, 0.00046),
}


def decimals(printed: float) -> int:
    text = repr(printed)
    return len(text.split(".")[1]) if "." in text else 0


def matches_printed(value: float, printed: float, rel: float) -> bool:
    """Within ``rel`` of the printed number, or equal to it once rounded to its printed digits
    (a value printed as 0.00031 cannot be checked closer than half a unit in its last place)."""
    return (abs(value - printed) <= rel * abs(printed)
            or round(value, decimals(printed)) == printed)


def matches_truncated(value: float, printed: float) -> bool:
    """The printed value is ``value`` cut (not rounded) to the printed digits."""
    scale = 10 ** decimals(printed)
    return math.trunc(value * scale) / scale == printed


@pytest.mark.parametrize("ident", sorted(TABLE_III))
def test_table_iii_on_the_papers_grid(ident):
    name, fmax, mmax, fres, mres = TABLE_III[ident]
    s = spec.grid_spec(load(DESIGNS / name), 10)
    for value, printed in [(s.force_norm_max_n, fmax), (s.torque_norm_max_nm, mmax),
                           (s.force_resolution_n, fres), (s.torque_resolution_nm, mres)]:
        assert matches_printed(value, printed, 0.002), (value, printed)


def test_table_ii_on_the_papers_grid(baseline):
    s = spec.grid_spec(baseline, 10)
    rel = 0.005
    checks = [
        (s.workspace_mm[0], 73.2), (s.workspace_mm[1], 65.2), (s.workspace_mm[2], 53.1),
        (s.force_range_n["x"][1], 15.03),
        (s.force_range_n["y"][0], -15.03), (s.force_range_n["y"][1], 15.03),
        (s.force_range_n["z"][0], -25.02), (s.force_range_n["z"][1], 22.09),
        (s.torque_range_nm["x"][1], 0.38), (s.torque_range_nm["y"][1], 0.33),
        (s.torque_range_nm["z"][1], 0.43),
        (s.torque_resolution_nm, 0.0003),
    ]
    for value, printed in checks:
        assert matches_printed(value, printed, rel), (value, printed)
    # Torque ranges are symmetric (the table prints +-).
    for axis in "xyz":
        lo, hi = s.torque_range_nm[axis]
        assert lo == pytest.approx(-hi, rel=1e-12)
    # The two entries the paper truncates rather than rounds (docs/model.md says so).
    assert matches_truncated(s.force_range_n["x"][0], -14.41)       # computed -14.4197
    assert matches_truncated(s.force_resolution_n, 0.0118)          # computed 0.011874
    assert not matches_printed(s.force_resolution_n, 0.0118, rel)   # rounding would give 0.0119


def test_converged_limits_of_the_baseline(baseline):
    s = spec.converged_spec(baseline)
    expected = {  # ../shared/notes/model-conventions.md, 4 significant digits
        "workspace": ([73.22, 65.16, 53.06], s.workspace_mm),
        "Fx": ([-14.43, 15.03], s.force_range_n["x"]),
        "Fy": ([-15.03, 15.03], s.force_range_n["y"]),
        "Fz": ([-25.10, 22.17], s.force_range_n["z"]),
        "full_scale": ([15.03, 15.03, 25.10, 0.3805, 0.3347, 0.4266], s.full_scale),
    }
    for key, (want, got) in expected.items():
        assert np.allclose(got, want, rtol=6e-4), key


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted(DESIGNS.glob("*.toml")), ids=lambda p: p.stem)
def test_converged_limits_bound_every_grid(path):
    """The converged extremes contain any sampled grid, and an odd dense grid gets close."""
    d = load(path)
    conv = spec.converged_spec(d)
    for n in (10, 17):
        g = spec.grid_spec(d, n)
        for key in ("force_range_n", "torque_range_nm"):
            for axis in "xyz":
                assert getattr(conv, key)[axis][0] <= getattr(g, key)[axis][0] + 1e-9
                assert getattr(conv, key)[axis][1] >= getattr(g, key)[axis][1] - 1e-9
        assert conv.force_norm_max_n >= g.force_norm_max_n - 1e-9
        assert conv.force_resolution_n >= g.force_resolution_n - 1e-12
    dense = spec.grid_spec(d, 25)
    for axis in "xyz":
        assert np.allclose(dense.force_range_n[axis], conv.force_range_n[axis], rtol=2e-3)


def test_converged_extremes_are_attained(baseline):
    """The report's extremes are values of the model at real poses, not overshoot: the force
    norm maximum is reached at a corner of the box."""
    from delta6.core import model
    corners = np.array(np.meshgrid(*[[-np.pi / 6, np.pi / 6]] * 3, indexing="ij")).reshape(3, -1).T
    best = np.linalg.norm(model.base_force(baseline, corners), axis=-1).max()
    assert spec.converged_spec(baseline).force_norm_max_n == pytest.approx(best, rel=1e-12)


def test_full_scale_is_the_larger_range_magnitude(baseline):
    s = spec.converged_spec(baseline)
    ranges = [s.force_range_n[a] for a in "xyz"] + [s.torque_range_nm[a] for a in "xyz"]
    assert np.allclose(spec.full_scale(baseline), [max(abs(lo), abs(hi)) for lo, hi in ranges])


def test_scaling_laws_of_table_iii():
    """Halving every length doubles forces and resolution; k scales everything by itself."""
    base = spec.converged_spec(load(DESIGNS / "delta6.toml"))
    half = spec.converged_spec(load(DESIGNS / "half-scale.toml"))
    stiff = spec.converged_spec(load(DESIGNS / "stiff.toml"))
    assert half.force_norm_max_n == pytest.approx(2 * base.force_norm_max_n, rel=1e-9)
    assert half.torque_norm_max_nm == pytest.approx(base.torque_norm_max_nm, rel=1e-9)
    assert half.force_resolution_n == pytest.approx(2 * base.force_resolution_n, rel=1e-6)
    assert stiff.force_norm_max_n == pytest.approx(1.5 * base.force_norm_max_n, rel=1e-9)
    assert stiff.torque_resolution_nm == pytest.approx(1.5 * base.torque_resolution_nm, rel=1e-6)


def test_cli_json_has_the_documented_keys(capsys):
    assert main(["design", str(DESIGNS / "delta6.toml"), "--grid", "10", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("workspace_mm", "force_range_n", "torque_range_nm", "force_norm_max_n",
                "torque_norm_max_nm", "force_resolution_n", "torque_resolution_nm",
                "full_scale"):
        assert key in out
    assert len(out["workspace_mm"]) == 3 and len(out["full_scale"]) == 6
    assert set(out["force_range_n"]) == {"x", "y", "z"}
    assert out["force_range_n"]["z"] == pytest.approx([-25.0179, 22.0949], abs=1e-4)


@pytest.mark.slow
def test_cli_table_of_all_variants(capsys):
    files = [str(DESIGNS / TABLE_III[i][0]) for i in sorted(TABLE_III)]
    assert main(["design", *files, "--grid", "10"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = [line.split() for line in lines[2:6]]
    assert [r[0] for r in rows] == ["delta6", "half-scale", "stiff", "half-scale-stiff"]
    for row, ident in zip(rows, sorted(TABLE_III)):
        _, fmax, mmax, fres, _ = TABLE_III[ident]
        # The last four columns: |Fmax|, |Mmax|, Fres, Mres (the design's own come first).
        assert float(row[-4]) == pytest.approx(fmax, abs=0.006)
        assert float(row[-3]) == pytest.approx(mmax, abs=0.0006)
        assert float(row[-2]) == pytest.approx(fres, abs=6e-6)
