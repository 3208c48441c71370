"""``simlab estimate``: the empirical MDP of a dataset directory or an external count table,
written as ``mdp.npz`` with a JSON summary and the entropy plot (thesis 3.2.5, Fig. 4.8).

The model itself (T = n(s,a,s')/n(s,a), the self-loop of an unvisited pair, entropy,
the dense and sparse paths) is :mod:`simlab.data.count_model`; its names are importable
from here too.

**Unvisited pairs for planners**: the self-loop keeps T a distribution, but a
planner must not read "never tried" as "a free stay". The rule stored in the model's
metadata (``meta_json``: ``{"unvisited": "mask" | "self-loop", "action_set": {...}}``)
says what consumers do with ``visited == False``: ``mask`` (the default) means training
and replay only choose among visited actions of a state (``valid = visited``; a state with
no visited action keeps all of them); ``self-loop`` is the old rule, the self-loop taken
at face value. T itself is the same under both rules (so old results stay bit-identical).

**Action sets**: the model records its :class:`~simlab.base.actions.ActionSet` (number of
actions, direction numbering, speed of an 8-action set), from the dataset or from the
``--n-actions/--convention/--speed`` of a count table; files without it are simlab's 16
primitives.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import SIMLAB16, ActionSet, ActionSetOptions
from simlab.base.errors import ConfigError, warn
from simlab.base.io import atomic_write, atomic_write_json, ensure_new, output_transaction
from simlab.base.options import command, option
from simlab.data.count_model import (
    HISTOGRAM_EDGES,
    SPARSE_CELLS,
    STORAGES,
    UNVISITED_RULES,
    CountModel,
    SparseCountModel,
    check_unvisited_rule,
    count_transitions,
    coverage_report,
    empirical_mdp,
    entropy_bits,
    mean_entropy_per_action,
    sparse_count_model,
    sparse_from_dense_counts,
    transition_matrix,
    use_sparse,
    valid_actions,
)
from simlab.data.schema import N_ACTIONS
from simlab.physics.inputs import load_arena_config, load_discretizer

__all__ = ["HISTOGRAM_EDGES", "SPARSE_CELLS", "STORAGES", "UNVISITED_RULES", "CountModel",
           "EstimateConfig", "EstimateResult", "SparseCountModel", "check_unvisited_rule",
           "count_transitions", "coverage_report", "empirical_mdp", "entropy_bits", "estimate",
           "mean_entropy_per_action", "output_paths", "sparse_count_model",
           "sparse_from_dense_counts", "transition_matrix", "use_sparse", "valid_actions"]


@dataclass(frozen=True)
class EstimateResult:
    """What :func:`estimate` produced: the model, the output paths and the summary."""

    mdp: CountModel | SparseCountModel
    npz: Path
    summary_path: Path
    plot: Path | None
    summary: dict[str, Any] = field(repr=False)


def output_paths(out: str | os.PathLike[str]) -> tuple[Path, Path, Path]:
    """``(mdp.npz, mdp.json summary, mdp_entropy.png plot)`` for ``out = mdp.npz``."""
    out = Path(out)
    if out.suffix != ".npz":
        raise ConfigError("the model file must end in .npz", path=out, fix="e.g. --out mdp.npz")
    return out, out.with_suffix(".json"), out.with_name(f"{out.stem}_entropy.png")


def _inside(path: Path, directory: Path) -> bool:
    try:
        path.resolve().relative_to(directory.resolve())
    except ValueError:
        return False
    return True


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _floats(values: NDArray[np.float64]) -> list[float | None]:
    """JSON-safe floats: NaN (an action never tried) becomes null."""
    return [_finite(v) for v in values]


@dataclass(frozen=True, kw_only=True)
class EstimateConfig(ActionSetOptions):
    """Options of ``simlab estimate`` / :func:`estimate`. The action-set group
    (:class:`~simlab.base.actions.ActionSetOptions`) and ``action_set`` (an
    :class:`~simlab.base.actions.ActionSet`, from Python) describe a count table only; a dataset
    records its own (decision: the group is refused for a dataset, as the CLI always did)."""

    COMMAND = "estimate"
    ARGUMENTS = ("dataset", "out")

    dataset: Path | None = option(None, "dataset directory written by `simlab collect`",
                                  positional=True)
    out: Path = option(help="model file mdp.npz (summary .json and _entropy.png beside it)")
    counts: Path | None = option(
        None, "instead of a dataset: CSV/JSON table with s, a, s_next, count")
    arena: Any | None = option(
        None, "arena whose goals define goal_masks (default: the dataset's)")
    states: Any | None = option(
        None, "states file: S and centres for --counts; checked against a dataset")
    n_states: int | None = option(None, "number of states for --counts without --states")
    unvisited: str = option("mask", "unvisited (s, a): mask = planners never choose them; "
                            "self-loop = the old rule, a free stay")
    plot: bool = option(True, "the entropy bar plot (--no-plot skips it)")
    overwrite: bool = option(False, "replace existing outputs")
    storage: str = option("auto", "model storage: auto = sparse CSR when S*A*S > 2e7 cells, "
                          "else dense; dense; sparse", choices=STORAGES)
    action_set: Any | None = option(None, "ActionSet of a count table (Python only)", cli=False)

    def validate(self) -> None:
        if self.arena is not None:
            from simlab.physics.arena import check_arena_option

            check_arena_option(self.arena)
        if (self.dataset is None) == (self.counts is None):
            raise ConfigError("give either a dataset directory or --counts FILE (exactly one)",
                              key="source")
        check_unvisited_rule(self.unvisited)
        use_sparse(1, 1, self.storage)  # an unknown storage names its field here
        if self.action_set is not None and not isinstance(self.action_set, ActionSet):
            raise ConfigError(f"expected an ActionSet, got {self.action_set!r}",
                              key="action_set")
        if self.action_set_given and (self.dataset is not None or self.action_set is not None):
            raise ConfigError("--n-actions/--convention/--speed describe a --counts table; a "
                              "dataset records its own action set", key="n_actions",
                              fix="drop them, or re-import the data with the right convention")
        if self.n_actions is not None or self.convention is not None:
            self.make_action_set(N_ACTIONS)  # a bad convention names its field here
        if self.n_states is not None:
            validation.whole(self.n_states, "n_states", minimum=1)
        output_paths(self.out)

    def table_action_set(self) -> ActionSet:
        """The action set of a count table: ``action_set``, else the group's fields."""
        return self.action_set if self.action_set is not None else self.make_action_set(N_ACTIONS)


@dataclass
class _Source:
    """What the dataset or the count table gives the model (arrays as loaded)."""

    counts: NDArray[np.int64] | None
    action_set: ActionSet | None
    summary: dict[str, Any]
    triples: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]] | None = None
    shape: tuple[int, int] | None = None
    states_hash: str | None = None
    centres: NDArray[np.float64] | None = None
    goals: Any = None
    bounds: list[float] | None = None
    blocked_by_action: NDArray[np.float64] | None = None


@command(EstimateConfig)
def estimate(cfg: EstimateConfig) -> EstimateResult:
    """Estimate the empirical MDP of a dataset directory or an external count table.

    Takes an :class:`EstimateConfig` or its fields (``estimate(dataset, out, plot=False)``):

    * ``dataset``: a directory written by ``simlab collect`` (validated: checksums,
      schema, discretizer). Its manifest supplies S, the centres and the goals.
    * ``out``: the model file ``*.npz``; the JSON summary and the entropy plot go beside
      it (``mdp.json``, ``mdp_entropy.png``). Must not lie inside ``dataset``.
    * ``counts``: instead of ``dataset``, a CSV/JSON count table (:mod:`simlab.data.counts`).
    * ``arena``: arena name/path/``ArenaConfig`` whose goals define ``goal_masks``
      (default for a dataset: the goals recorded in its manifest).
    * ``states``: states file or discretizer: S and the centres for a count table; for a
      dataset, its hash must equal the manifest's (else DataError).
    * ``n_states``: S for a count table without ``states`` (default: largest index + 1).
    * ``n_actions``/``convention``/``speed`` or ``action_set``: what the action indices of
      a count table mean (default simlab's 16 primitives). A dataset carries its own
      (``TransitionDataset.action_set``, SIMLAB16 for datasets without one).
    * ``plot``: write the mean-entropy-per-action bar plot (thesis Fig. 4.8).
    * ``overwrite``: replace existing output files.
    * ``unvisited``: rule for unvisited (s, a), ``mask`` (default) or ``self-loop``,
      stored in the model's metadata (module docstring).
    * ``storage``: ``auto`` (sparse when ``S * A * S`` > :data:`SPARSE_CELLS`), ``dense``
      or ``sparse`` (module docstring, "Sparse path"); the sparse path's ``mdp`` is a
      :class:`SparseCountModel` and its npz holds the CSR arrays instead of ``counts``/``T``.

    Returns:
        :class:`EstimateResult`. The (dense) npz holds ``counts`` (S, A, S) int64, ``T`` (S, A, S),
        ``visited`` (S, A) bool, ``entropy`` (S, A) bits, ``mean_entropy`` (A,) bits and,
        when the centres are known, ``centres`` (S, 2) m; with goals also
        ``goal_names`` (G,) unicode, ``goal_masks`` (G, S) bool and ``R`` (G, S, A);
        with a known arena ``bounds`` (4,) ``x_min, y_min, x_max, y_max`` m; and
        ``meta_json`` (JSON: ``action_set``, ``unvisited``).
    """
    npz_path, summary_path, plot_path = output_paths(cfg.out)
    if cfg.dataset is not None and _inside(npz_path, Path(cfg.dataset)):
        raise ConfigError(
            "the model must not be written inside the dataset directory (Parquet readers "
            "of the directory would choke on it)", path=npz_path,
            fix="choose --out outside the dataset, e.g. beside it",
        )
    for p in (npz_path, summary_path, *((plot_path,) if cfg.plot else ())):
        ensure_new(p, overwrite=cfg.overwrite)
    disc = None if cfg.states is None else load_discretizer(cfg.states)
    arena_cfg = None if cfg.arena is None else load_arena_config(cfg.arena)
    if disc is not None and arena_cfg is not None:  # the goals are found through the centres
        from simlab.base.statecheck import check_centres_in_arena

        check_centres_in_arena(disc.centres, arena_cfg, source=str(cfg.states)
                               if isinstance(cfg.states, str | os.PathLike) else None)
    src = _from_dataset(cfg, disc, arena_cfg) if cfg.dataset is not None else \
        _from_counts(cfg, disc, arena_cfg)
    mdp = _count_model(src, cfg.storage)
    arrays, goal_info = _model_arrays(mdp, src, cfg.unvisited)
    summary = _summary(mdp, src, cfg.unvisited, goal_info)
    summary["files"] = {"npz": str(npz_path), "summary": str(summary_path),
                        "plot": str(plot_path) if cfg.plot else None}
    _write_outputs(cfg, mdp, arrays, summary, (npz_path, summary_path, plot_path))
    return EstimateResult(mdp=mdp, npz=npz_path, summary_path=summary_path,
                          plot=plot_path if cfg.plot else None, summary=summary)


def _from_dataset(cfg: EstimateConfig, disc: Any, arena_cfg: Any) -> _Source:
    """Counts, action set, centres, goals and blocked fractions of a dataset directory."""
    from simlab.data.dataset import open_dataset
    from simlab.data.goals import goals_from_manifest

    dataset = cfg.dataset
    ds = open_dataset(dataset, validate=True,
                      expected_discretizer=None if disc is None else disc.content_hash())
    S, A = ds.n_states, ds.n_actions
    names = getattr(ds, "action_names", None)
    action_set = None if names is not None else (getattr(ds, "action_set", None) or SIMLAB16)
    if action_set is None:  # named non-primitive actions (e.g. the social task's 22)
        if cfg.action_set is not None:
            raise ConfigError("the dataset's actions are not motion primitives",
                              path=dataset, key="action_set", fix="leave action_set out")
    elif cfg.action_set is not None and cfg.action_set != action_set:
        raise ConfigError(
            f"the dataset records {action_set.describe()}, not {cfg.action_set.describe()}",
            path=dataset, key="action_set",
            fix="leave --n-actions/--convention/--speed out for a dataset")
    if action_set is not None and action_set.n_actions != A:
        raise ConfigError(f"the dataset has {A} actions but records "
                          f"{action_set.describe()}", path=dataset, key="action_set")
    ds.warn_if_incomplete("the model")
    if ds.table.num_rows == 0:
        warn(f"{ds.directory}: the dataset holds no transitions (its manifest lists "
             f"{len(ds.manifest['parts'])} parts): the model is estimated from 0 "
             "transitions and every (s, a) is unvisited (collect data into it first)")
    a_col = ds.column("a")
    triples = (ds.column("s"), a_col, ds.column("s_next"))
    arena = ds.manifest["arena"]
    bounds = None if arena_cfg is None else [float(v) for v in arena_cfg.bounds]
    if bounds is None and arena.get("bounds") is not None:
        bounds = [float(v) for v in arena["bounds"]]
    tries = np.bincount(a_col, minlength=A)
    hits = np.bincount(a_col, weights=ds.column("blocked").astype(np.float64), minlength=A)
    parts = ds.manifest["parts"]
    source = {
        "dataset": str(Path(dataset)),
        "arena": arena["name"],
        "simulator": ds.manifest.get("simulator"),
        "pose_source": ds.manifest["pose_source"],
        "discretizer_hash": ds.discretizer_hash,
        "seed": ds.manifest["seed"],
        "workers": ds.manifest["workers"],
        "complete": ds.manifest.get("complete"),
        "simulated_hours": float(
            sum(max((e["t_end"] for e in parts if e["worker"] == w), default=0.0)
                for w in range(int(ds.manifest["workers"])))) / 3600.0,
    }
    return _Source(
        counts=None if use_sparse(S, A, cfg.storage) else count_transitions(*triples, S, A),
        triples=triples, shape=(S, A),
        action_set=action_set, summary={"source": source},
        states_hash=ds.discretizer_hash, centres=ds.centres,
        goals=arena_cfg if arena_cfg is not None else goals_from_manifest(
            arena.get("goals", [])),
        bounds=bounds,
        blocked_by_action=np.divide(hits, tries, out=np.full(A, np.nan), where=tries > 0))


def _count_model(src: _Source, storage: str) -> CountModel | SparseCountModel:
    """The dense model of the counts, or the sparse one (:func:`use_sparse`)."""
    if src.counts is None:  # a dataset on the sparse path: its triples only
        S, A = src.shape  # type: ignore[misc]
        return sparse_count_model(*src.triples, S, A)  # type: ignore[misc]
    S, A = src.counts.shape[:2]
    if use_sparse(S, A, storage):
        return sparse_from_dense_counts(src.counts)
    return empirical_mdp(src.counts)


def _from_counts(cfg: EstimateConfig, disc: Any, arena_cfg: Any) -> _Source:
    """Counts and centres of an external count table (its action set as given)."""
    from simlab.data.counts import check_action_width, load_counts

    n_states = cfg.n_states
    if disc is not None and n_states is not None and int(n_states) != disc.n_states:
        raise ConfigError(
            f"--n-states {n_states} disagrees with the states file ({disc.n_states} states)",
            key="n_states",
        )
    action_set = cfg.table_action_set()
    table = load_counts(cfg.counts, n_states=disc.n_states if disc is not None else n_states,
                        n_actions=action_set.n_actions)  # type: ignore[arg-type]
    check_action_width(table, given=cfg.n_actions is not None or cfg.action_set is not None)
    source = {
        "counts": str(Path(cfg.counts)),  # type: ignore[arg-type]
        "format": table.format,
        "rows": table.rows,
        "duplicate_rows_summed": table.duplicates,
        # the file's own top-level fields (ISIR: actioncount, timecount), as given
        "file_metadata": dict(table.metadata),
        "n_states_from": "states file" if disc is not None else (
            "--n-states" if n_states is not None else "largest index + 1"),
    }
    return _Source(
        counts=table.counts, action_set=action_set, summary={"source": source},
        states_hash=None if disc is None else disc.content_hash(),
        centres=None if disc is None else np.asarray(disc.centres, dtype=np.float64),
        goals=arena_cfg,
        bounds=None if arena_cfg is None else [float(v) for v in arena_cfg.bounds])


def _action_set_json(src: _Source) -> dict[str, Any] | None:
    """The action set record; None for a dataset of named non-primitive actions."""
    return None if src.action_set is None else src.action_set.to_json()


def _model_arrays(mdp: CountModel | SparseCountModel, src: _Source, unvisited: str
                  ) -> tuple[dict[str, Any], dict[str, list[int]] | None]:
    """The arrays of ``mdp.npz`` and the goal states (None without centres or goals)."""
    from simlab.data.goals import goal_state_masks

    # the states fingerprint: train and replay check it against their states file
    meta = {"action_set": _action_set_json(src), "unvisited": unvisited}
    if src.states_hash is not None:
        meta["states_hash"] = src.states_hash
    if isinstance(mdp, SparseCountModel):
        meta["storage"] = "sparse-csr"
        arrays: dict[str, Any] = {
            "shape": np.array([mdp.n_states, mdp.n_actions, mdp.n_states], dtype=np.int64),
            "indptr": mdp.indptr, "indices": mdp.indices,
            "probabilities": mdp.probabilities, "counts_data": mdp.counts}
    else:
        arrays = {"counts": mdp.counts, "T": mdp.T}
    arrays.update({
        "visited": mdp.visited,
        "entropy": mdp.entropy,
        "mean_entropy": mdp.mean_entropy,
        "meta_json": np.array(json.dumps(meta)),
    })
    goal_info = None
    if src.bounds is not None:
        arrays["bounds"] = np.asarray(src.bounds, dtype=np.float64)
    if src.centres is not None:
        arrays["centres"] = np.asarray(src.centres, dtype=np.float64)
        if src.goals is not None:
            names, masks = goal_state_masks(src.goals, src.centres)
            arrays["goal_names"] = names
            arrays["goal_masks"] = masks
            arrays["R"] = mdp.rewards(masks)
            goal_info = {str(n): [int(s) for s in np.flatnonzero(m)]
                         for n, m in zip(names, masks, strict=True)}
    return arrays, goal_info


def _summary(mdp: CountModel | SparseCountModel, src: _Source, unvisited: str,
             goal_info: dict[str, list[int]] | None) -> dict[str, Any]:
    """The JSON summary beside the model (without its ``files`` entry)."""
    n_masked = int((~valid_actions(mdp.visited)).sum()) if unvisited == "mask" else 0
    summary = dict(src.summary)
    summary.update({
        "n_states": mdp.n_states,
        "n_actions": mdp.n_actions,
        "transitions": int(mdp.counts.sum()),
        **({"storage": "sparse-csr", "stored_entries": mdp.nnz}
           if isinstance(mdp, SparseCountModel) else {}),
        "coverage": coverage_report(mdp),
        "entropy_bits": {
            "per_action": _floats(mdp.mean_entropy),
            "slow_mean": _finite(mdp.slow_mean_entropy) if mdp.n_actions == 16 else None,
            "fast_mean": _finite(mdp.fast_mean_entropy) if mdp.n_actions == 16 else None,
            "overall_mean_visited": float(mdp.entropy[mdp.visited].mean())
            if mdp.visited.any() else None,
        },
        "action_set": _action_set_json(src),
        "unvisited": unvisited,
        "unvisited_rule": (
            "T[s, a, s] = 1, flagged visited[s, a] = False; "
            + ("planners choose only visited actions (mask)" if unvisited == "mask"
               else "planners may choose them as a free stay (self-loop)")),
        "masked_pairs": n_masked,
        "states_without_data": int((~mdp.visited.any(axis=1)).sum()),
    })
    if src.blocked_by_action is not None:
        summary["blocked_fraction_per_action"] = _floats(src.blocked_by_action)
    if goal_info is not None:
        summary["goal_states"] = goal_info
    return summary


def _write_outputs(cfg: EstimateConfig, mdp: CountModel | SparseCountModel, arrays: dict[str, Any],
                   summary: dict[str, Any], paths: tuple[Path, Path, Path]) -> None:
    """Write the model, the plot and the summary: all of them, or none."""
    npz_path, summary_path, plot_path = paths
    finals = (npz_path, summary_path, *((plot_path,) if cfg.plot else ()))
    with output_transaction(npz_path.parent, finals, overwrite=cfg.overwrite,
                            what="model output") as txn:
        with atomic_write(txn.path(npz_path), "wb") as fh:
            np.savez_compressed(fh, **arrays)
        if cfg.plot:
            from simlab.data.plots import plot_entropy_per_action

            title = None
            if mdp.n_actions == 16:
                title = (f"Mean entropy per action — slow {mdp.slow_mean_entropy:.2f} bits, "
                         f"fast {mdp.fast_mean_entropy:.2f} bits "
                         f"({summary['coverage']['fraction_visited']:.0%} of (s, a) visited)")
            means = ({"slow_mean": mdp.slow_mean_entropy, "fast_mean": mdp.fast_mean_entropy}
                     if mdp.n_actions == 16 else {})  # NaN without data, and no warning
            plot_entropy_per_action(mdp.mean_entropy, txn.path(plot_path), title=title,
                                    **means)
        atomic_write_json(txn.path(summary_path), summary)
