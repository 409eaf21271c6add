"""Training a residual model for the microcontroller (``delta6 train --target mcu``).

The model corrects the wrench the board already computes (the base model: the analytical one,
or a unit's calibrated one) from features the board has for free: that wrench, the encoder
counts, their steps over one model period and play operators on the counts
(:mod:`delta6.core.int8net`). A small float MLP is trained on them (torch, Adam, MSE in % FS,
early stopping on the time-ordered held-out tail), quantized after training
(:mod:`delta6.core.int8quant`), and scored three ways on the held-out tail: the float network,
its ONNX export through onnxruntime, and the integer reference the board mirrors bit for bit.

torch is needed here only (the ``train`` extra); everything downstream (codegen, evaluation)
reads the JSON model file with numpy.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from delta6.core import accuracy, int8net, int8quant
from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.int8quant import FeatureSpec, FloatNet
from delta6.core.model import ENCODER_COUNT_RAD
from delta6.core.residualmodel import ResidualModel
from delta6.core.spec import full_scale
from delta6.learning.dataset import check_motion

#: The default features over the analytical model (docs/ondevice-model.md says why): the base
#: wrench, the counts, the base wrench's step over one model period, and plays of 4, 16 and 64
#: counts, into one hidden layer of 16.
DEFAULT_FEATURES = (FeatureSpec("wrench"), FeatureSpec("counts"), FeatureSpec("wrench_step", 1),
                    FeatureSpec("play", 4), FeatureSpec("play", 16), FeatureSpec("play", 64))
DEFAULT_HIDDEN = (16,)
#: Over a calibration: a linear map of the counts (36 multiply-accumulates). The calibrated
#: model already carries the history terms; wider inputs and hidden layers gained nothing on
#: held-out data there and cost the cycles the calibrated solve needs (docs/ondevice-model.md).
CALIBRATED_FEATURES = (FeatureSpec("counts"),)
CALIBRATED_HIDDEN = ()
#: Base wrench input steps: full scale is 2^14 steps, so int16 holds +-2 full scales.
INPUT_STEPS_PER_FS = 16384.0
MIN_SAMPLES = 200
#: A log's rate counts as whole within this share of it (its median step jitters).
WHOLE_RATE_TOLERANCE = 0.01

Progress = Callable[[str], None]


@dataclass
class McuSettings:
    features: tuple = DEFAULT_FEATURES
    hidden: tuple = DEFAULT_HIDDEN
    epochs: int = 30
    batch: int = 1024
    learning_rate: float = 3e-3
    patience: int = 6
    holdout: float = 0.2
    seed: int = 0


@dataclass
class McuResult:
    model: ResidualModel
    float_net: FloatNet
    report: dict = field(default_factory=dict)


def default_settings(base, **overrides) -> McuSettings:
    """The settings for a residual over ``base``: the analytical model's default network, or
    the linear map of the counts over a calibrated model; ``overrides`` replace fields."""
    if getattr(base, "name", "") == "calibrated":
        overrides = {"features": CALIBRATED_FEATURES, "hidden": CALIBRATED_HIDDEN, **overrides}
    return McuSettings(**overrides)


class AnalyticalBase:
    """The analytical model as the base (the estimator protocol: ``name``, ``predict``)."""

    name = "analytical"

    def __init__(self, design: Design):
        self.design = design

    def predict(self, log) -> np.ndarray:
        from delta6.core import model
        return model.wrench(self.design, np.asarray(log.theta, dtype=float))


class CalibratedBase:
    """A unit's calibrated model as the base (what the board computes when built with
    ``codegen --calibration``); the model file names the calibration it was trained over."""

    name = "calibrated"

    def __init__(self, design: Design, calibration):
        from delta6.core.calibrated import CalibratedModel
        self.model = CalibratedModel(design, calibration)
        self.calibration = calibration
        self.calibration_name = calibration.name
        self.calibration_hash = calibration.hash32()

    def predict(self, log) -> np.ndarray:
        return self.model.predict(log)


class McuEstimator:
    """An on-chip residual model file run through the integer reference over its base, as the
    board runs it (an estimator for ``delta6.evaluation.tablev``, named after the file)."""

    def __init__(self, path: str | Path, design: Design, calibration=None):
        from delta6.core import residualmodel
        self.path = Path(path)
        self.name = self.path.stem
        self.model = residualmodel.load(self.path)
        # A model over the analytical model runs over it whatever calibration the table also
        # scores (as a host model does); one over a calibration needs that very calibration.
        if self.model.base == "analytical":
            calibration = None
        residualmodel.check_base(self.model, design, calibration)
        # Its row is what the board would stream: a model no image runs has no such row.
        residualmodel.check_cost(self.model.net.macs, design, calibration, str(self.path))
        self.design = design
        self.base = (AnalyticalBase(design) if calibration is None
                     else CalibratedBase(design, calibration))

    def predict(self, log) -> np.ndarray:
        net = self.model.net
        base_wrench = self.base.predict(log)
        u, counts, valid = board_inputs(log, self.design, base_wrench, net.input_scale)
        stride = int8net.stride_for(net, nominal_rate(log.t)) if len(log.t) > 1 else 1
        correction, _ = int8net.run(net, u, counts, stride=stride, valid=valid)
        return int8net.apply_output(base_wrench, correction, net.output_step).astype(float)


def nominal_rate(t: np.ndarray) -> float:
    steps = np.diff(np.asarray(t, dtype=float))
    if len(steps) == 0 or not np.all(np.isfinite(steps)) or np.median(steps) <= 0:
        raise UserError("the log's time column does not increase: cannot tell its sample rate")
    return float(1.0 / np.median(steps))


def board_inputs(log, design: Design, base_wrench: np.ndarray, input_scale: np.ndarray):
    """What the board feeds the network: the base wrench in input steps, the signed counts,
    and which rows have a base wrench."""
    valid = np.all(np.isfinite(base_wrench), axis=1) & np.all(np.isfinite(log.theta), axis=1)
    safe = np.where(valid[:, None], base_wrench, 0.0)
    base = int8net.quantize_input(safe, input_scale)
    theta = np.where(valid[:, None], np.asarray(log.theta, dtype=float), 0.0)
    counts = np.clip(np.round(theta / ENCODER_COUNT_RAD), -8192, 8191).astype(np.int64)
    return base, counts, valid


def input_scale_for(design: Design) -> np.ndarray:
    return (INPUT_STEPS_PER_FS / full_scale(design)).astype(np.float32)


def train_mcu(log, design: Design, base, *, name: str, settings: McuSettings = McuSettings(),
              progress: Progress | None = None, source: str = "") -> McuResult:
    """Fit, quantize and score a residual model over ``base`` on ``log``."""
    import torch

    started = time.perf_counter()
    say = progress or (lambda text: None)
    n = len(log.t)
    if n < MIN_SAMPLES:
        raise UserError(f"too few samples to train on: {n} (at least {MIN_SAMPLES})")
    check_motion(log.theta, source or "the log")
    fs = full_scale(design)
    rate = nominal_rate(log.t)
    if not (round(rate) >= 1 and abs(rate - round(rate)) <= WHOLE_RATE_TOLERANCE * rate):
        # The model's steps are samples of its rate, which the board must sample at.
        raise UserError(f"{source or 'the log'}: sampled at {rate:.4g} Hz, not a whole number of "
                        "Hz a board samples at: record the calibration log at the board's rate")
    base_wrench = base.predict(log)
    scale = input_scale_for(design)
    u, counts, valid = board_inputs(log, design, base_wrench, scale)
    reference = np.asarray(log.wrench, dtype=float)
    valid &= np.all(np.isfinite(reference), axis=1)
    features = tuple(settings.features)
    v = int8net.feature_values(features, u, counts, valid=valid).astype(float)
    target = np.where(valid[:, None], 100.0 * (reference - base_wrench) / fs, 0.0)
    split = int(round(n * (1.0 - settings.holdout)))
    train_rows = np.flatnonzero(valid[:split])
    held_rows = split + np.flatnonzero(valid[split:])
    if len(train_rows) < MIN_SAMPLES or len(held_rows) < 20:
        raise UserError("too few valid samples for training and a held-out tail")
    gain = 1.0 / np.maximum(v[train_rows].std(axis=0), 1.0)

    torch.manual_seed(settings.seed)
    torch.set_num_threads(1)   # tiny layers: threads cost more than they bring
    rng = np.random.default_rng(settings.seed)
    layers, width = [], v.shape[1]
    for h in settings.hidden:
        layers += [torch.nn.Linear(width, h), torch.nn.ReLU()]
        width = h
    layers.append(torch.nn.Linear(width, 6))
    net = torch.nn.Sequential(*layers)
    opt = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
    x_all = torch.tensor(v * gain, dtype=torch.float32)
    y_all = torch.tensor(target, dtype=torch.float32)
    # Early stopping on the last part of the training rows (the held-out tail stays unseen).
    cut = int(len(train_rows) * 0.85)
    fit_rows, stop_rows = train_rows[:cut], train_rows[cut:]
    best, best_loss, waited = None, np.inf, 0
    for epoch in range(settings.epochs):
        net.train()
        order = rng.permutation(fit_rows)
        for i in range(0, len(order), settings.batch):
            rows = torch.as_tensor(order[i:i + settings.batch])
            opt.zero_grad()
            loss = torch.mean((net(x_all[rows]) - y_all[rows]) ** 2)
            loss.backward()
            opt.step()
        net.eval()
        with torch.no_grad():
            rows = torch.as_tensor(stop_rows)
            stop_loss = float(torch.mean((net(x_all[rows]) - y_all[rows]) ** 2))
        say(f"epoch {epoch + 1}/{settings.epochs}: held-back loss {stop_loss:.4f} (% FS)^2")
        if stop_loss < best_loss - 1e-6:
            best_loss, waited = stop_loss, 0
            best = [p.detach().clone() for p in net.parameters()]
        else:
            waited += 1
            if waited >= settings.patience:
                break
    params = [p.numpy().astype(float) for p in best]
    float_net = FloatNet(rate_hz=float(round(rate)), input_scale=scale, features=features,
                         input_gain=gain, weights=tuple(params[0::2]), biases=tuple(params[1::2]),
                         output_gain=fs / 100.0)
    say("quantizing")
    try:
        q = int8quant.quantize(float_net, v[train_rows])
    except ValueError as exc:   # a trained network the integer engine cannot represent
        raise UserError(f"the trained network cannot be quantized for the board: {exc}; "
                        "try another --seed or --hidden") from None
    model = ResidualModel(name=name, design_name=design.name, design_hash=design.hash32(),
                          base=base.name if base.name in ("analytical", "calibrated") else
                          "calibrated", net=q,
                          calibration_name=getattr(base, "calibration_name", None),
                          calibration_hash=getattr(base, "calibration_hash", None))
    float_correction = float_net.forward(v)
    int_correction, _ = int8net.run(q, u, counts, valid=valid)
    estimates = {
        "base": base_wrench,
        "float": base_wrench + float_correction,
        "int8": int8net.apply_output(base_wrench, int_correction, q.output_step).astype(float),
    }
    held = {k: accuracy.percentiles(e[held_rows], reference[held_rows], fs, (95, 99, 100))
            for k, e in estimates.items()}
    report = {
        "log": source, "samples": int(n), "rate_hz": rate, "base": base.name,
        "features": [f"{f.kind}({f.param})" if f.param else f.kind for f in features],
        "hidden": list(settings.hidden), "macs": q.macs, "seed": settings.seed,
        "heldout": f"last {settings.holdout:.0%} of the log",
        "heldout_p99_pct": {k: [round(x, 4) for x in t["p99"]] for k, t in held.items()},
        "heldout_p95_pct": {k: [round(x, 4) for x in t["p95"]] for k, t in held.items()},
        "quantization_loss_p99_pct": [round(a - b, 4) for a, b in
                                      zip(held["int8"]["p99"], held["float"]["p99"])],
        "seconds": round(time.perf_counter() - started, 1),
    }
    model = ResidualModel(**{**model.__dict__, "training": report})
    return McuResult(model=model, float_net=float_net, report=report)


def export_onnx(net: FloatNet, path: str | Path, metadata: dict | None = None) -> Path:
    """The float network as ONNX: input ``features`` (batch, n_in) float32, the raw feature
    values; output ``correction`` (batch, 6) in N and N*m. Built node by node (no torch)."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    def const(name, value):
        return numpy_helper.from_array(np.asarray(value, dtype=np.float32), name)

    n_in = len(net.input_gain)
    inits = [const("input_gain", net.input_gain), const("output_gain", net.output_gain)]
    nodes = [helper.make_node("Mul", ["features", "input_gain"], ["h0"])]
    h = "h0"
    for i, (w, b) in enumerate(zip(net.weights, net.biases)):
        inits += [const(f"w{i}", w), const(f"b{i}", b)]
        nodes.append(helper.make_node("Gemm", [h, f"w{i}", f"b{i}"], [f"g{i}"], transB=1))
        h = f"g{i}"
        if i < len(net.weights) - 1:
            nodes.append(helper.make_node("Relu", [h], [f"r{i}"]))
            h = f"r{i}"
    nodes.append(helper.make_node("Mul", [h, "output_gain"], ["correction"]))
    graph = helper.make_graph(
        nodes, "delta6_residual",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, ["batch", n_in])],
        [helper.make_tensor_value_info("correction", TensorProto.FLOAT, ["batch", 6])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)],
                              producer_name="delta6 train --target mcu")
    model.ir_version = 8
    for key, value in (metadata or {}).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, str(value)
    onnx.checker.check_model(model)
    path = Path(path)
    onnx.save(model, str(path))
    return path


def onnx_correction(path: str | Path, v: np.ndarray) -> np.ndarray:
    """The ONNX float network's corrections for feature values ``v`` (onnxruntime, CPU)."""
    import onnxruntime
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(["correction"], {"features": np.asarray(v, dtype=np.float32)})[0]
