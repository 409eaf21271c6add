"""Training (torch): Adam on the MSE of standardised wrenches, early stopping on a held-out
tail of the log, the best checkpoint kept. Seeded: the same log, preset and seed give the same
weights on the same machine and thread count."""
from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import torch

from delta6.learning import nets
from delta6.learning.dataset import Dataset
from delta6.learning.presets import Preset

#: Windows per forward pass when scoring (memory bound, not a hyperparameter).
EVAL_CHUNK = 8192


@dataclass
class EpochReport:
    epoch: int
    max_epochs: int
    train_loss: float
    holdout_loss: float
    best_loss: float
    best_epoch: int
    lr: float
    seconds: float


@dataclass
class Trained:
    module: torch.nn.Module
    preset: Preset
    history: list[EpochReport] = field(default_factory=list)
    stopped: str = ""
    seconds: float = 0.0

    @property
    def best(self) -> EpochReport:
        return min(self.history, key=lambda r: r.holdout_loss)


#: Training threads unless told otherwise. One: these networks are small, and on a machine
#: shared with other jobs a second thread spends its time waiting (measured 4-40 times slower).
DEFAULT_THREADS = 1


def train(data: Dataset, preset: Preset, *, seed: int = 0, threads: int = DEFAULT_THREADS,
          progress: Callable[[EpochReport], None] | None = None) -> Trained:
    """Train ``preset``'s network on ``data`` (its time-ordered split); returns the best
    checkpoint on the held-out tail."""
    recipe = preset.recipe
    torch.set_num_threads(threads)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    module = nets.build(preset.net, data.window)
    x = torch.from_numpy(data.inputs)
    y = torch.from_numpy(data.targets)
    split = data.split(recipe.holdout)
    x_fit, y_fit, x_hold, y_hold = x[:split], y[:split], x[split:], y[split:]
    optimiser = torch.optim.Adam(module.parameters(), lr=recipe.lr)
    scheduler = (torch.optim.lr_scheduler.ReduceLROnPlateau(
        optimiser, factor=0.5, patience=recipe.lr_decay_patience)
        if recipe.lr_decay_patience else None)
    per_epoch = max(recipe.batch, int(round(recipe.epoch_fraction * split)))
    result = Trained(module=module, preset=preset)
    best_state, best_loss, best_epoch = None, math.inf, 0
    started = time.perf_counter()
    for epoch in range(1, recipe.max_epochs + 1):
        module.train()
        order = torch.from_numpy(rng.permutation(split)[:per_epoch])
        total = 0.0
        for start in range(0, len(order), recipe.batch):
            batch = order[start:start + recipe.batch]
            optimiser.zero_grad(set_to_none=True)
            loss = torch.nn.functional.mse_loss(module(x_fit[batch]), y_fit[batch])
            loss.backward()
            optimiser.step()
            total += loss.item() * len(batch)
        holdout = mse(module, x_hold, y_hold)
        if scheduler is not None:
            scheduler.step(holdout)
        if holdout < best_loss:
            best_loss, best_epoch = holdout, epoch
            best_state = copy.deepcopy(module.state_dict())
        report = EpochReport(epoch, recipe.max_epochs, total / len(order), holdout, best_loss,
                             best_epoch, optimiser.param_groups[0]["lr"],
                             time.perf_counter() - started)
        result.history.append(report)
        if progress:
            progress(report)
        if epoch - best_epoch >= recipe.patience:
            result.stopped = f"early stop: no better held-out loss for {recipe.patience} epochs"
            break
        if recipe.max_minutes is not None and report.seconds > 60 * recipe.max_minutes:
            result.stopped = f"time budget of {recipe.max_minutes:g} min reached"
            break
    else:
        result.stopped = f"maximum of {recipe.max_epochs} epochs reached"
    module.load_state_dict(best_state)
    module.eval()
    result.seconds = time.perf_counter() - started
    return result


def mse(module: torch.nn.Module, x: torch.Tensor, y: torch.Tensor) -> float:
    module.eval()
    total = 0.0
    with torch.no_grad():
        for start in range(0, len(x), EVAL_CHUNK):
            pred = module(x[start:start + EVAL_CHUNK])
            total += float(torch.nn.functional.mse_loss(pred, y[start:start + EVAL_CHUNK],
                                                        reduction="sum"))
    return total / (len(x) * y.shape[1])


def predict(module: torch.nn.Module, inputs: np.ndarray) -> np.ndarray:
    """Standardised outputs for standardised windows (torch; the reference for the export)."""
    module.eval()
    with torch.no_grad():
        return np.concatenate([module(torch.from_numpy(inputs[s:s + EVAL_CHUNK])).numpy()
                               for s in range(0, len(inputs), EVAL_CHUNK)])
