"""Exported ONNX models compute what the torch networks compute, and carry their model card."""
from __future__ import annotations

import numpy as np
import onnx
import pytest

from delta6.learning import nets
from delta6.learning.card import ModelCard
from delta6.learning.export import max_difference
from delta6.learning.presets import KINDS, PRESETS


@pytest.mark.parametrize("kind", KINDS)
def test_onnx_equals_torch_on_random_windows(tiny_models, kind):
    path, fitted = tiny_models[kind]
    rng = np.random.default_rng(1)
    for batch in (1, 3, 64):       # the batch dimension is free
        x = rng.normal(size=(batch, 25, 6)).astype(np.float32) * 2
        assert max_difference(fitted.trained.module, path, x) <= 1e-5
    assert not path.with_name(path.name + ".partial").exists()


@pytest.mark.parametrize("kind", KINDS)
def test_the_model_card_travels_in_metadata_props(tiny_models, baseline, kind):
    path, fitted = tiny_models[kind]
    props = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    assert ModelCard.from_props(props, path.name) == fitted.card
    assert props["delta6.design_hash"] == f"0x{baseline.hash32():08x}"
    assert props["delta6.kind"] == kind and props["delta6.window"] == "25"
    assert "holdout_pct_fs" in props["delta6.training"]


def test_paper_preset_sizes_are_the_papers_table_iv():
    counts = {k: nets.parameter_count(nets.build(p.net, 25)) for k, p in PRESETS["paper"].items()}
    assert round(counts["transformer"] / 1e3, 1) == 102.4
    assert round(counts["lstm"] / 1e3, 1) == 202.5
    assert round(counts["gru"] / 1e3, 1) == 152.1
