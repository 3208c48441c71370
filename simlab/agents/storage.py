"""Save and load Q-tables, models and agents without pickle.

Files are ``.npz`` archives (:mod:`simlab.agents.npzfile`) of plain numeric arrays plus one ``meta_json``
array (a 0-d numpy unicode string holding JSON). They are written atomically
(temporary name, then rename) and loaded with ``allow_pickle=False``.

* Q-table: ``Q`` (S, A) float64, its greedy policy ``greedy`` (S,) int64 (argmax over
  the valid actions, :mod:`simlab.agents.policy`; ``valid`` (S, A) bool is one of the
  extra arrays when some actions were never tried), any extra arrays you pass, and
  metadata.
* Count model: ``n_sa`` (S, A), ``r_sum`` (S, A), and the observed triples
  ``triple_s``, ``triple_a``, ``triple_next``, ``triple_count`` (n,) int64.
* Window model: ``n_sa``, ``slot_pair`` (n,), ``win_state`` / ``win_reward``
  (n, H), ``win_fill``, ``win_pos`` (n,).
* Agent: its config (JSON), ``Q`` and its model arrays prefixed ``model_``.
  A loaded agent continues learning exactly where it stopped, except for the
  Generator, which the caller passes again.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from simlab.agents import kernels as K
from simlab.agents.agents import (
    ModelBasedAgent,
    PassiveObserverAgent,
    QLearningAgent,
    RMaxAgent,
    SlidingWindowAgent,
    TabularAgent,
)
from simlab.agents.config import config_to_dict
from simlab.agents.npzfile import load_npz, write_npz
from simlab.agents.policy import masked_argmax, qtable_mask
from simlab.agents.sparse_model import CountModel
from simlab.agents.window_model import WindowModel
from simlab.base.errors import ConfigError, DataError

__all__ = [
    "load_agent",
    "load_model",
    "load_npz",
    "load_q_table",
    "save_agent",
    "save_model",
    "save_q_table",
]

def save_q_table(
    path: str | os.PathLike[str],
    Q: np.ndarray,
    *,
    metadata: dict[str, Any] | None = None,
    arrays: dict[str, np.ndarray] | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``Q`` (S, A) (+ extra ``arrays``, JSON ``metadata``) to ``path``.

    The file also carries ``greedy`` (S,) int64, the policy
    :func:`simlab.agents.greedy` returns: the argmax of each row over ``arrays["valid"]``
    (S, A) bool when given (unless ``metadata["unvisited"]`` is ``"self-loop"``), so that a
    reader who never heard of the mask still acts on tried actions only.
    """
    Q = np.asarray(Q, dtype=np.float64)
    if Q.ndim != 2:
        raise ConfigError(f"expected an (S, A) array, got shape {Q.shape}", key="Q")
    extra = dict(arrays or {})
    if {"Q", "meta_json", "greedy"} & set(extra):
        raise ConfigError("extra arrays may not be named 'Q', 'greedy' or 'meta_json'",
                          key="arrays")
    meta = {"kind": "q_table", **(metadata or {})}
    greedy = masked_argmax(Q, qtable_mask(extra, meta))
    return write_npz(path, {"Q": Q, "greedy": greedy, **extra}, meta, overwrite)


def load_q_table(path: str | os.PathLike[str]) -> tuple[np.ndarray, dict[str, Any]]:
    """``(Q (S, A) float64, metadata)`` from a file written by :func:`save_q_table`
    (or any npz with a 2-D array ``Q``)."""
    arrays, meta = load_npz(path, ("Q",))
    Q = arrays["Q"]
    if Q.ndim != 2 or not np.issubdtype(Q.dtype, np.floating):
        raise ConfigError(
            f"expected a 2-D float array, got {Q.dtype} {Q.shape}", path=path, key="Q"
        )
    return Q.astype(np.float64), meta


def _model_arrays(model: CountModel | WindowModel) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    if isinstance(model, CountModel):
        ss, aa, nn, cc = K.count_model_triples(model)
        arrays = {
            "n_sa": model.n_sa.copy(),
            "r_sum": model.r_sum.copy(),
            "triple_s": ss,
            "triple_a": aa,
            "triple_next": nn,
            "triple_count": cc,
        }
        return arrays, {"model": "count", "n_states": model.n_states, "n_actions": model.n_actions}
    if isinstance(model, WindowModel):
        sp, ws, wr, wf, wp = K.window_model_export(model)
        arrays = {
            "n_sa": model.n_sa.copy(),
            "slot_pair": sp,
            "win_state": ws,
            "win_reward": wr,
            "win_fill": wf,
            "win_pos": wp,
        }
        meta = {
            "model": "window",
            "n_states": model.n_states,
            "n_actions": model.n_actions,
            "window": model.window,
        }
        return arrays, meta
    raise ConfigError(f"cannot save a {type(model).__name__}", key="model")


def _model_from_arrays(
    arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Any, prefix: str = ""
) -> CountModel | WindowModel:
    kind = meta.get("model")
    S, A = int(meta["n_states"]), int(meta["n_actions"])

    def get(name: str) -> np.ndarray:
        key = prefix + name
        if key not in arrays:
            raise ConfigError(f"missing array {key}", path=path)
        return arrays[key]

    if kind == "count":
        ss, aa = get("triple_s"), get("triple_a")
        nn, cc = get("triple_next"), get("triple_count")
        n_sa, r_sum = get("n_sa"), get("r_sum")
        model = CountModel(S, A, max(1, len(ss)))
        K.count_model_load(
            model,
            ss.astype(np.int64),
            aa.astype(np.int64),
            nn.astype(np.int64),
            cc.astype(np.int64),
            r_sum.astype(np.float64),
        )
        if not np.array_equal(model.n_sa, n_sa):
            raise DataError(f"{path}: counts n_sa disagree with the saved triples")
        return model
    if kind == "window":
        H = int(meta["window"])
        sp = get("slot_pair").astype(np.int64)
        model = WindowModel(S, A, H, max(1, len(sp)))
        K.window_model_load(
            model,
            get("n_sa").astype(np.int64),
            sp,
            get("win_state").astype(np.int64),
            get("win_reward").astype(np.float64),
            get("win_fill").astype(np.int64),
            get("win_pos").astype(np.int64),
        )
        return model
    raise DataError(f"{path}: unknown model kind {kind!r}")


def save_model(
    path: str | os.PathLike[str], model: CountModel | WindowModel, *, overwrite: bool = False
) -> Path:
    """Write a count or window model to ``path`` (npz, no pickle)."""
    arrays, meta = _model_arrays(model)
    return write_npz(path, arrays, {"kind": "model", **meta}, overwrite)


def load_model(path: str | os.PathLike[str]) -> CountModel | WindowModel:
    """Read a model written by :func:`save_model`."""
    arrays, meta = load_npz(path)
    if meta.get("kind") != "model":
        raise ConfigError("not a simlab model file (meta kind != 'model')", path=path)
    return _model_from_arrays(arrays, meta, path)


_AGENT_CLASSES: dict[str, type[TabularAgent]] = {
    "QLearningAgent": QLearningAgent,
    "ModelBasedAgent": ModelBasedAgent,
    "SlidingWindowAgent": SlidingWindowAgent,
    "RMaxAgent": RMaxAgent,
    "PassiveObserverAgent": PassiveObserverAgent,
}


def save_agent(
    path: str | os.PathLike[str], agent: TabularAgent, *, overwrite: bool = False
) -> Path:
    """Write an agent (config, Q-tables, model, step counter) to ``path``."""
    cls = type(agent).__name__
    if cls not in _AGENT_CLASSES:
        raise ConfigError(f"cannot save a {cls}", key="agent")
    meta: dict[str, Any] = {
        "kind": "agent",
        "class": cls,
        "name": agent.name,
        "n_states": agent.n_states,
        "n_actions": agent.n_actions,
        "config": config_to_dict(agent.config),
    }
    arrays: dict[str, np.ndarray] = {"Q": agent.Q}
    inner: Any = agent
    if isinstance(agent, PassiveObserverAgent):
        meta["controlling"] = agent.controlling
        arrays["actor_Q"] = agent.actor.Q
        inner = agent.actor
    if isinstance(inner, ModelBasedAgent | RMaxAgent):
        m_arrays, m_meta = _model_arrays(inner.model)
        arrays.update({f"model_{k}": v for k, v in m_arrays.items()})
        meta["model_meta"] = m_meta
        meta["steps"] = inner.steps
    return write_npz(path, arrays, meta, overwrite)


def load_agent(path: str | os.PathLike[str], rng: np.random.Generator) -> TabularAgent:
    """Rebuild an agent saved by :func:`save_agent`; ``rng`` drives its future choices."""
    from simlab.agents.config import (
        ModelBasedConfig,
        PassiveObserverConfig,
        QLearningConfig,
        RMaxConfig,
        SlidingWindowConfig,
        config_from_dict,
    )

    arrays, meta = load_npz(path, ("Q",))
    if meta.get("kind") != "agent" or meta.get("class") not in _AGENT_CLASSES:
        raise ConfigError("not a simlab agent file", path=path)
    cls = _AGENT_CLASSES[meta["class"]]
    config_cls = {
        QLearningAgent: QLearningConfig,
        ModelBasedAgent: ModelBasedConfig,
        SlidingWindowAgent: SlidingWindowConfig,
        RMaxAgent: RMaxConfig,
        PassiveObserverAgent: PassiveObserverConfig,
    }[cls]
    config = config_from_dict(config_cls, meta["config"])
    agent = cls(int(meta["n_states"]), int(meta["n_actions"]), config, rng)
    agent.name = meta.get("name", agent.name)
    inner: Any = agent
    if isinstance(agent, PassiveObserverAgent):
        agent.observer.Q[...] = arrays["Q"]
        agent.actor.Q[...] = arrays["actor_Q"]
        agent.controlling = meta.get("controlling", "actor")
        inner = agent.actor
    else:
        agent.Q[...] = arrays["Q"]
    if "model_meta" in meta:
        inner.model = _model_from_arrays(arrays, meta["model_meta"], path, prefix="model_")
        inner.steps = int(meta.get("steps", 0))
    return agent
