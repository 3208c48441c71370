"""The replay's inputs, checked against each other before the robot moves.

* **Q-tables**: one ``q_<goal>.npz`` per goal of the arena in a directory (the files
  ``simlab train`` writes; read with :func:`simlab.agents.storage.load_npz`), or a
  mapping ``goal -> Q``. Each must be ``(S, A)``: S the states of the discretizer, A the
  actions of their **action set** (``action_set`` in the metadata; 16 simlab
  primitives for files without one; an 8-action table without one is refused). All goals
  must share one action set. A saved ``valid`` (S, A) mask (unvisited pairs) travels with
  them: the replay never executes a masked action. A goal without a file, a wrong shape,
  non-finite values or disagreeing action sets raise :class:`~simlab.base.errors.ConfigError`
  naming the file.
* **The empirical MDP** (for the predicted rate): the ``mdp.npz`` given, or the one the
  Q-tables record in their metadata (``mdp``). Its ``T`` must be ``(S, A, S)`` with the
  Q-tables' action set, its centres (if stored) those of the discretizer and its goals
  those of the arena.
* **Goal masks**: from the arena's goals and the discretizer's centres with the
  estimator's rule (:func:`simlab.data.goals.goal_state_masks`).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.actions import SIMLAB16, ActionSet, action_set_from_metadata
from simlab.base.errors import ConfigError, warn
from simlab.data.goals import is_state_goal
from simlab.data.manifest import physics_rate

#: Number of simlab motion primitives (thesis 3.2: 8 directions x 2 speeds).
N_ACTIONS = 16


def q_file_name(goal: str) -> str:
    """File name of a goal's Q-table in a ``simlab train`` directory (``q_<goal>.npz``;
    characters other than letters, digits, ``_.-`` become ``_``, as ``simlab train``
    writes them)."""
    return f"q_{re.sub(r'[^A-Za-z0-9_.-]+', '_', goal)}.npz"


@dataclass(frozen=True)
class QTables:
    """Per-goal Q-tables in the arena's goal order.

    ``Q`` ``(G, S, A)`` float64; ``names`` the goal names; ``files`` the file of each
    (None for tables passed in memory); ``metadata`` the JSON metadata of each file;
    ``action_set`` what their A actions mean; ``valid`` ``(G, S, A)`` bool actions the
    policy may choose (None: all).
    """

    Q: NDArray[np.float64]
    names: tuple[str, ...]
    files: tuple[str | None, ...]
    metadata: tuple[dict[str, Any], ...]
    source: str | None
    action_set: ActionSet = SIMLAB16
    valid: NDArray[np.bool_] | None = None


def load_qtables(qtables: str | os.PathLike[str] | Mapping[str, Any], goal_names: tuple[str, ...],
                 n_states: int, states_source: str | None = None, *,
                 action_set: ActionSet | None = None) -> QTables:
    """Load and check the Q-table of every goal in ``goal_names`` (see the module doc).

    ``action_set`` is required for in-memory tables of other than 16 actions; for files it
    must agree with their metadata when given.
    """
    from simlab.agents.storage import load_npz, load_q_table

    where = f" of {states_source}" if states_source else ""
    tables, files, metas, valids = [], [], [], []
    if isinstance(qtables, Mapping):
        source = None
        for g in goal_names:
            if g not in qtables:
                raise ConfigError(f"no Q-table for goal {g!r}", key="qtables",
                                  fix=f"give one per goal: {', '.join(goal_names)}")
            tables.append(np.asarray(qtables[g], dtype=np.float64))
            files.append(None)
            metas.append({} if action_set is None else {"action_set": action_set.to_json()})
            valids.append(None)
    else:
        directory = Path(qtables)
        source = str(directory)
        if not directory.is_dir():
            raise ConfigError("Q-table directory not found", path=directory,
                              fix="give the --out directory of `simlab train`")
        for g in goal_names:
            path = directory / q_file_name(g)
            if not path.is_file():
                present = sorted(p.name for p in directory.glob("q_*.npz"))
                raise ConfigError(
                    f"no Q-table for goal {g!r} (expected {path.name})", path=directory,
                    key="qtables",
                    fix=f"train every goal of the arena (`simlab train --goals all`); found: "
                        f"{', '.join(present) or 'no q_*.npz file'}",
                )
            Q, meta = load_q_table(path)
            arrays, _ = load_npz(path)
            tables.append(Q)
            files.append(str(path))
            metas.append(meta)
            valids.append(arrays.get("valid"))
    aset = _common_action_set(goal_names, tables, files, metas, action_set)
    expected = (n_states, aset.n_actions)
    for g, Q, f, v in zip(goal_names, tables, files, valids, strict=True):
        if Q.shape != expected:
            raise ConfigError(
                f"Q-table of goal {g!r} has shape {Q.shape}, expected {expected}: "
                f"{n_states} states{where} x {aset.describe()}",
                path=f, key="Q",
                fix="train on an MDP estimated with the same states file",
            )
        if not np.all(np.isfinite(Q)):
            raise ConfigError(f"Q-table of goal {g!r} has NaN or infinite values", path=f, key="Q")
        if v is not None and (v.shape != expected or v.dtype != bool):
            raise ConfigError(f"expected a {expected} bool mask, got {v.dtype} {v.shape}",
                              path=f, key="valid")
    valid = None
    if any(v is not None for v in valids):
        valid = np.stack([np.ones(expected, dtype=bool) if v is None else v for v in valids])
    return QTables(Q=np.stack(tables), names=tuple(goal_names), files=tuple(files),
                   metadata=tuple(metas), source=source, action_set=aset, valid=valid)


def _common_action_set(goal_names: tuple[str, ...], tables: list[Any], files: list[Any],
                       metas: list[dict[str, Any]], given: ActionSet | None) -> ActionSet:
    """The one action set of all the Q-tables (ConfigError naming the file that differs)."""
    found: ActionSet | None = None
    for g, Q, f, meta in zip(goal_names, tables, files, metas, strict=True):
        n = int(Q.shape[1]) if Q.ndim == 2 else 0
        if n not in (8, 16):
            raise ConfigError(f"Q-table of goal {g!r} has {n} actions; the robot has 8 or 16",
                              path=f, key="Q", fix="train on an MDP of the robot's actions")
        aset = given if (f is None and given is not None) else action_set_from_metadata(
            meta, n, where=f or f"Q-table of goal {g!r}")
        if given is not None and aset != given:
            raise ConfigError(f"Q-table of goal {g!r} has {aset.describe()}, expected "
                              f"{given.describe()}", path=f, key="action_set")
        if found is not None and aset != found:
            raise ConfigError(f"Q-table of goal {g!r} has {aset.describe()}, the others "
                              f"{found.describe()}", path=f, key="action_set",
                              fix="train all goals on the same MDP")
        found = aset
    return found if found is not None else (given or SIMLAB16)


def discover_mdp(qtables: QTables) -> str | None:
    """The ``mdp.npz`` the Q-tables were trained on, from their metadata: the path as
    ``train`` was given it (from here, then from the Q-tables' directory), then the absolute
    path ``train`` resolved it to (``mdp_resolved``; a replay run from another directory
    than the training finds it so). When the Q-tables name an MDP that none of these
    reaches, a warning says so (the prediction is then missing for a reason the user can
    fix with ``--mdp``); None."""
    named = []
    for meta, f in zip(qtables.metadata, qtables.files, strict=True):
        value = meta.get("mdp")
        if not isinstance(value, str) or not value:
            continue
        named.append(value)
        candidates = [Path(value)]
        if not Path(value).is_absolute() and f is not None:
            candidates.append(Path(f).parent / value)
        resolved = meta.get("mdp_resolved")
        if isinstance(resolved, str) and resolved:
            candidates.append(Path(resolved))
        for path in candidates:
            if path.is_file():
                return str(path)
    if named:
        warn(f"the Q-tables were trained on {named[0]}, which is not found from here: no "
             "MDP-predicted rate (pass --mdp FILE to get it)")
    return None


@dataclass(frozen=True)
class ModelInputs:
    """The empirical model the prediction needs.

    ``T`` ``(S, A, S)``; ``source`` the file; from the estimator's summary beside it
    (``mdp.json``) and the dataset's manifest when they can be found:
    ``dataset_seconds_per_transition`` (robot seconds per transition of the walk),
    ``dataset`` (its directory) and ``primitive_params`` (the motion-primitive parameters
    it was collected with, a dict; None for a kinematic dry-run dataset) and ``physics_hz``
    (the physics rate it stepped at, :func:`simlab.data.manifest.physics_rate`); None when
    unknown.
    """

    T: NDArray[np.float64]
    source: str | None
    dataset_seconds_per_transition: float | None
    dataset: str | None = None
    primitive_params: dict[str, Any] | None = None
    action_set: ActionSet = SIMLAB16
    physics_hz: float | None = None
    valid: NDArray[np.bool_] | None = None


def load_model(mdp: Any, discretizer: Any, goal_names: tuple[str, ...],
               goal_masks: NDArray[np.bool_], *,
               action_set: ActionSet | None = None) -> ModelInputs:
    """Load an ``mdp.npz`` (or an :class:`~simlab.data.mdp.EmpiricalMDP`) and
    check it against the discretizer, the arena's goals and (when given) the Q-tables'
    ``action_set``."""
    from simlab.data.mdp import EmpiricalMDP, load_mdp

    m = mdp if isinstance(mdp, EmpiricalMDP) else load_mdp(mdp)
    src = None if m.source is None else str(m.source)
    S = discretizer.n_states
    if m.action_set is None:
        raise ConfigError(f"{m.n_actions} actions and no action_set record", path=src,
                          key="action_set", fix="re-estimate it with --n-actions and --convention")
    if action_set is not None and m.action_set != action_set:
        raise ConfigError(
            f"the MDP has {m.action_set.describe()}, the Q-tables {action_set.describe()}",
            path=src, key="action_set", fix="replay the Q-tables trained on this MDP")
    A = m.action_set.n_actions
    if m.T.shape != (S, A, S):
        raise ConfigError(
            f"T has shape {m.T.shape}, expected ({S}, {A}, {S}) for the states file",
            path=src, key="T", fix="estimate the MDP with the same states file",
        )
    if m.centres is not None and not np.allclose(m.centres, discretizer.centres, atol=1e-9):
        raise ConfigError(
            "the MDP was estimated with other states (its centres differ from the states "
            "file's)", path=src, key="centres",
            fix="use the states file the dataset was collected with",
        )
    if m.goal_names:
        # Every arena goal replayed must be one of the MDP's, covering the same states (a
        # subset is fine); state-id goals (``s18``, as train --goal-states names them) are
        # defined by their ids alone.
        foreign = [g for g in goal_names if g not in m.goal_names and not is_state_goal(g)]
        if foreign:
            raise ConfigError(
                f"goals {foreign} are not among the MDP's goals {list(m.goal_names)}",
                path=src, key="goal_names", fix="estimate with the same arena",
            )
        for i, g in enumerate(goal_names):
            if (g in m.goal_names and not is_state_goal(g)
                    and not np.array_equal(m.goal_mask(g), goal_masks[i])):
                raise ConfigError(
                    f"goal {g!r} covers other states in the MDP than in the arena",
                    path=src, key="goal_masks", fix="estimate with the same arena and states",
                )
    pace, dataset, primitive, physics_hz = None, None, None, None
    doc = _read_json(Path(src).with_suffix(".json")) if src is not None else None
    if doc is not None:
        try:
            hours = float(doc["source"]["simulated_hours"])
            n = int(doc["transitions"])
            pace = hours * 3600.0 / n if hours > 0 and n > 0 else None
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            pace = None
        name = (doc.get("source") or {}).get("dataset") if isinstance(doc.get("source"), dict) \
            else None
        if isinstance(name, str):
            for candidate in (Path(name), Path(src).parent / name):  # type: ignore[arg-type]
                manifest = _read_json(candidate / "_manifest.json")
                if manifest is not None:
                    dataset = str(candidate)
                    physics_hz = physics_rate(manifest)
                    prim = (manifest.get("parameters") or {}).get("primitive")
                    # Only a physics walk's parameters are motion primitives.
                    if manifest.get("simulator", "physics") == "physics" and isinstance(prim,
                                                                                        dict):
                        primitive = prim
                    break
    return ModelInputs(T=np.asarray(m.T, dtype=np.float64), source=src,
                       dataset_seconds_per_transition=pace, dataset=dataset,
                       primitive_params=primitive, action_set=m.action_set, valid=m.valid,
                       physics_hz=physics_hz)


def _read_json(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError):
        return None
    return doc if isinstance(doc, dict) else None


def primitive_params_for(model: ModelInputs | None, params: Any) -> tuple[Any, str]:
    """The primitive parameters to replay with, and where they come from.

    The robot must drive the primitives the model was estimated from: with ``params``
    None, the dataset's recorded parameters are used (the defaults if unknown); given
    ``params`` that differ from the dataset's (other than ``heading_source``) raise
    :class:`ConfigError`.
    """
    from dataclasses import asdict, fields

    from simlab.physics.motion import PrimitiveParams

    recorded = None if model is None else model.primitive_params
    if recorded is None:
        # only when no dataset was found at all (a kinematic dataset has no primitives)
        if model is not None and model.dataset is None and params is None:
            warn("the MDP carries no record of the motion primitives it was estimated from "
                 "(no dataset manifest beside it); replaying with the default primitives — "
                 "pass the real robot's settings (--primitives FILE.toml) if they differ")
        return (params, "given") if params is not None else (PrimitiveParams(), "default")
    names = {f.name for f in fields(PrimitiveParams)}
    if params is None:
        try:
            return PrimitiveParams.from_json(recorded), "dataset"
        except ConfigError as exc:
            raise ConfigError(
                f"the dataset's primitive parameters are not usable: {exc}",
                path=model.dataset, key="parameters.primitive",  # type: ignore[union-attr]
                fix="collect the dataset again with this version of simlab",
            ) from None
    given = asdict(params)
    diff = sorted(k for k in names - {"heading_source"} if k in recorded
                  and given[k] != recorded[k])
    if diff:
        shown = ", ".join(f"{k} {given[k]!r} vs {recorded[k]!r}" for k in diff[:4])
        raise ConfigError(
            f"the replay's motion primitives differ from those the MDP's dataset was "
            f"collected with ({shown})",
            path=model.dataset, key="parameters.primitive",  # type: ignore[union-attr]
            fix="replay with the dataset's parameters (leave params unset) or collect again",
        )
    return params, "given (same as the dataset's)"


def physics_rate_for(model: ModelInputs | None, hz: float | None) -> tuple[float, str]:
    """The physics rate (Hz) to replay at, and where it comes from.

    The robot should step the physics the model was estimated from: with ``hz`` None, the
    MDP's dataset's rate (a physics dataset whose manifest predates the record stepped at
    200 Hz), else the default rate. A given rate wins (checked against the minimum); when
    it differs from the dataset's the source says so, and replay.json records both.
    """
    from simlab.physics.rate import DEFAULT_HZ, check_rate

    recorded = None if model is None else model.physics_hz
    if hz is not None:
        hz = check_rate(hz)
        if recorded is not None and abs(recorded - hz) > 1e-9:
            return hz, f"given (the dataset stepped at {recorded:g} Hz)"
        return hz, "given"
    if recorded is not None:
        return check_rate(recorded, key="parameters.physics.hz"), "dataset"
    return DEFAULT_HZ, "default"
