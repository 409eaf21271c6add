"""The error distributions of several estimators on one log, one panel per axis: the share of
samples whose |error| exceeds x % FS (a complementary CDF on a log scale, so the tails that
Table V summarises stay visible). Headless matplotlib (the ``plots`` extra)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from delta6.core.accuracy import error_pct_fs
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.outputs import check_output_file, write_atomically


def check_plot_path(path: str | Path, option: str = "--plot") -> Path:
    """Refuse, before any work, a plot file that cannot be written: matplotlib missing, a
    folder that does not exist, or a name whose suffix is not an image format."""
    _matplotlib()
    from matplotlib.backend_bases import FigureCanvasBase

    path = check_output_file(path, option)
    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = plot_format(path)
    # Without a suffix matplotlib wrote NAME.png, a file no check had looked at.
    if not suffix:
        raise UserError(f"{option} {path}: give the image format as its suffix "
                        f"({path.name}.png, .svg or .pdf)")
    if suffix not in formats:
        raise UserError(f"{option} {path}: '.{suffix}' is not an image format matplotlib writes"
                        f" (one of {', '.join(sorted(formats))})")
    return path


def plot_format(path: Path) -> str:
    """The image format, named by the suffix (the file is written under a temporary name
    first, so matplotlib is told it rather than left to guess)."""
    return path.suffix.lower().lstrip(".")


def _matplotlib():
    try:
        import matplotlib
    except ImportError:
        raise UserError("--plot needs matplotlib: pip install 'delta6[plots]'") from None
    matplotlib.use("Agg")
    return matplotlib


def plot_errors(estimates: dict[str, np.ndarray], reference: np.ndarray, full_scale,
                path: str | Path, title: str = "") -> Path:
    """``estimates``: {row name: (n, 6) wrench}; writes the image to ``path`` atomically, in
    the format its suffix names."""
    path = check_plot_path(path)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5), sharey=True)
    n = len(reference)
    share = 1.0 - np.arange(n) / n          # share of samples at or above each sorted error
    for name, estimate in estimates.items():
        err = error_pct_fs(estimate, reference, full_scale)
        for axis, ax in enumerate(axes.flat):
            ax.step(np.sort(err[:, axis]), share, where="post", label=name, lw=1.2)
    for axis, ax in enumerate(axes.flat):
        ax.set_yscale("log")
        ax.set_ylim(max(0.5 / n, 1e-5), 1.0)
        ax.set_xlim(left=0)
        ax.axhline(0.01, color="grey", lw=0.6, ls=":")       # the p99 line
        ax.set_title(AXES[axis])
        ax.set_xlabel("|error|, % FS")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("share of samples above")
    axes[1, 0].set_ylabel("share of samples above")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title or "Error distributions (dotted: 1 % of samples, the p99)")
    fig.tight_layout()
    try:
        return write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=110,
                                                              format=plot_format(path)))
    finally:
        plt.close(fig)
