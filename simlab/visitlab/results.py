"""Saving, loading and plotting Visit-the-lab learning curves.

An output directory holds three files, all written atomically:

* ``curves.npz`` — ``labels`` (unicode, (R,)), ``configs`` (JSON text per run,
  unicode (R,)), and for run ``i``: ``returns_i`` float64 ``(n_seeds, n_trials)``
  reward per trial and ``q_i`` float64 ``(n_seeds, n_states, n_actions)`` final
  Q tables (read back with :func:`load_results`; no pickle);
* ``curves.png`` — thesis Fig. 4.1 style: the reward per trial averaged over seeds
  and over windows of ``n_trials / 100`` trials, with a band of one standard
  deviation within the window;
* ``summary.json`` — per run: plateau, trials to reach 90 % of it, wall time, and
  the full configuration.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError, DataError
from simlab.base.io import atomic_write, atomic_write_json, ensure_new, npz_problem
from simlab.base.options import CommandConfig, option
from simlab.visitlab.curves import TrainResult, smooth_curve, summarize_curve

FILES = ("curves.npz", "curves.png", "summary.json")

__all__ = ["FILES", "PlotConfig", "load_results", "plot_results", "save_results",
           "smooth_curve", "summarize_curve"]


def save_results(results: list[TrainResult], out_dir: str | os.PathLike[str], *,
                 overwrite: bool = False, title: str = "") -> dict[str, Path]:
    """Write the three files of ``results`` into ``out_dir``; returns their paths.

    Refuses to replace existing files unless ``overwrite``.
    """
    out = Path(out_dir)
    paths = {name: ensure_new(out / name, overwrite=overwrite, what=name) for name in FILES}
    out.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {
        "labels": np.array([r.label for r in results], dtype=np.str_),
        "configs": np.array([json.dumps(r.config) for r in results], dtype=np.str_),
    }
    for i, r in enumerate(results):
        arrays[f"returns_{i}"] = np.asarray(r.returns, dtype=np.float64)
        arrays[f"q_{i}"] = np.asarray(r.q, dtype=np.float64)
    with atomic_write(paths["curves.npz"], "wb") as fh:
        np.savez_compressed(fh, **arrays)
    plot_results(results, paths["curves.png"], title=title)
    atomic_write_json(paths["summary.json"], {
        "runs": [r.summary() | {"config": r.config} for r in results],
    })
    return paths


def load_results(path: str | os.PathLike[str]) -> list[TrainResult]:
    """Read a ``curves.npz`` written by :func:`save_results`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            labels = [str(x) for x in data["labels"]]
            configs = [json.loads(str(x)) for x in data["configs"]]
            out = []
            for i, label in enumerate(labels):
                out.append(TrainResult(label, data[f"returns_{i}"], data[f"q_{i}"], configs[i]))
    except KeyError as exc:
        raise DataError(f"{path}: not a Visit-the-lab curves file (no array {exc}; "
                        f"simlab visitlab train writes curves.npz)") from None
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise DataError(f"{path}: not a Visit-the-lab curves file: "
                        f"{npz_problem(path, exc)}") from None
    return out


def plot_results(results: list[TrainResult], path: str | os.PathLike[str], *,
                 title: str = "") -> None:
    """Plot the smoothed curves of ``results`` (one line and band each) to a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=120)
    for r in results:
        x, mean, std = smooth_curve(r.returns)
        (line,) = ax.plot(x, mean, label=r.label, lw=1.6)
        ax.fill_between(x, mean - std, mean + std, color=line.get_color(), alpha=0.2, lw=0)
    if results:
        cfg = results[0].config
        n_seeds = results[0].returns.shape[0]
        default = (f"{cfg.get('task', '')} ({cfg.get('variant', '')}), "
                   f"{n_seeds} seeds, {cfg.get('max_steps', '?')} steps per trial")
        ax.set_title(title or default, fontsize=10)
    ax.set_xlabel("trials")
    ax.set_ylabel("reward per trial")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png")
    plt.close(fig)


@dataclass(frozen=True, kw_only=True)
class PlotConfig(CommandConfig):
    """Options of ``simlab visitlab plot``: the runs of several curves files drawn by
    :func:`plot_results` on one figure."""

    COMMAND = "visitlab plot"

    curves: tuple[Path, ...] = option(help="curves.npz files", positional=True)
    labels: str | None = option(
        None, "comma-separated legend labels, one per curve in file order")
    title: str = option("", "plot title")
    out: Any = option(help="PNG to write")
    overwrite: bool = option(False, "replace an existing PNG")

    def validate(self) -> None:
        if not self.curves:
            raise ConfigError("no curves file given", key="curves")
        validation.spelled_path(self.out, "out")

    def label_list(self) -> list[str] | None:
        """The legend labels of ``labels`` (None: the runs' own)."""
        return None if self.labels is None else [x.strip() for x in self.labels.split(",")]
