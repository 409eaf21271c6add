"""The residual engine on the ATmega328P (avr-gcc 5.4, simavr) gives the numpy reference's
integers; the application links it only when a model header is present."""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

from delta6.build import appbuild, avrbuild
from delta6.core import int8net, residualmodel
from delta6.core.int8quant import FeatureSpec
from delta6.sim import residualbench
from delta6_codegen import render, render_model

from support.int8nets import random_features, random_int8net, trained_like


def _header_dir(tmp_path, net, design=None):
    model = residualmodel.ResidualModel(name="avr-test", design_name="delta6",
                                        design_hash=0x535534AF, base="analytical", net=net)
    gen = tmp_path / "generated"
    gen.mkdir(exist_ok=True)
    (gen / "delta6_model.h").write_text(render_model(model, "designs/delta6.toml", "m.json"))
    if design is not None:
        (gen / "delta6_design.h").write_text(render(design, "designs/delta6.toml"))
    return tmp_path, model


@pytest.mark.parametrize("kind, rate", [("trained", 250), ("linear", 200), ("random", 50)])
def test_avr_gives_the_reference_integers(tmp_path, kind, rate):
    rng = np.random.default_rng(42)
    samples = 1500
    base, counts, valid = residualbench.stream(samples)
    if kind == "trained":
        features = random_features(rng, 5)
        _, net = trained_like(rng, features, int8net.feature_values(features, base, counts),
                              hidden=(16,))
    elif kind == "linear":   # the default over a calibration: one layer over the counts
        features = (FeatureSpec("counts"),)
        _, net = trained_like(rng, features, int8net.feature_values(features, base, counts),
                              hidden=())
    else:
        net = random_int8net(rng)
    include, model = _header_dir(tmp_path, net)
    run = residualbench.run(include, samples=samples, rate_hz=rate)
    assert run.model_hash == model.hash32()
    stride = int8net.stride_for(net, rate)
    assert run.stride == stride
    np.testing.assert_array_equal(run.valid, valid)
    ref, _ = int8net.run(net, base, counts, stride=stride, valid=valid)
    mismatch = np.flatnonzero(np.any(run.correction != ref, axis=1))
    assert not len(mismatch), f"AVR differs from the reference from sample {mismatch[0]}"
    assert len(run.cycles) == valid.sum()


def _symbols(elf) -> str:
    return subprocess.run(["avr-nm", "-C", str(elf)], capture_output=True, text=True,
                          check=True).stdout


def test_the_engine_is_linked_only_with_a_model(tmp_path, baseline):
    plain = appbuild.build_app()
    assert "residual" not in _symbols(plain.elf)
    net = random_int8net(np.random.default_rng(3))
    include, _ = _header_dir(tmp_path, net, design=baseline)
    with_model = appbuild.build_app(include, name="delta6-app-model-test")
    symbols = _symbols(with_model.elf)
    assert "residual_state" in symbols and "kWeights0" in symbols
    assert with_model.sizes.flash > plain.sizes.flash
    assert with_model.sizes.flash <= avrbuild.NANO.flash_bytes
