"""Export a transition dataset as a Minari dataset (``minari`` extra).

Offline-RL libraries read Minari datasets; ``minari.load_dataset(dataset_id)`` then
gives the random walk with ``Discrete(S)`` observations (the Markov state) and
``Discrete(16)`` actions (the motion primitives).

Episodes: each worker's walk, in step order, cut into chunks of ``episode_length``
transitions (default: the dataset's part size, so that an episode never spans the
re-placement of the robot at a part boundary). A chunk is also cut where the walk is
not continuous in the state (``s`` of a step differs from ``s_next`` of the step
before, e.g. when an odometry pose source restarts at a part boundary). An episode
of n steps has n + 1 observations ``[s_0, s'_0, ..., s'_{n-1}]``; ``terminations`` are
all False (a random walk has no terminal state), ``truncations`` True on the last step.
Rewards are 0, or with ``goal`` the physics task's reward 1[s' in the goal area]
(states of the goal from :func:`simlab.data.goals.goal_state_masks`).
``infos`` carry ``pose`` (n + 1, 3) (m, m, rad; from the dataset's pose source), and
``blocked`` and ``t`` (n + 1, 1) (the step that produced the observation; False / the
start time for the first one).

Round trip: the dataset records an env spec, ``simlab/TableArenaStates-v0`` with the
dataset's Voronoi centres (``states``, JSON list in state order), arena (built-in name or
the ``arena=`` TOML path given to the export), action set, goal (``goal`` or the arena's
first goal when rewards are 0) and ``max_episode_steps = episode_length``, so
``minari.load_dataset(id).recover_environment()`` is the physics env whose observations,
actions and rewards are those of the data. Pose sources other than ``odometry`` map to the
simulator's truth (the env has no LIDAR localizer).

Writing is one transaction: the id is validated (Minari's id syntax, an existing id
refused unless ``overwrite``) before anything is written; the dataset is built under a
temporary datasets root beside Minari's (``MINARI_DATASETS_PATH`` pointed there for the
duration of the call, so the export is not thread-safe) and renamed into place, so a
failure never leaves a partial dataset that would break ``minari list local``. A killed
export (SIGKILL) leaves its hidden staging root; the next export removes it, at once when
its process is gone (:func:`remove_dead_staging`: simlab's roots only, never one a live
export holds the lock of).

The options of :func:`export_minari` (``simlab export-minari``) are the fields of
:class:`ExportMinariConfig`.
"""

from __future__ import annotations

import itertools
import os
import shutil
import tempfile
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError, warn
from simlab.base.io import put_back, set_aside
from simlab.base.options import CommandConfig, command, option


@dataclass(frozen=True)
class MinariExportResult:
    """The exported dataset: its id, episode and step counts and where Minari keeps it."""

    dataset_id: str
    episodes: int
    steps: int
    path: str


def _episode_bounds(worker: np.ndarray, s: np.ndarray, s_next: np.ndarray,
                    episode_length: int) -> list[tuple[int, int]]:
    """``[(start, stop))`` row ranges of the episodes (rows sorted by worker, step)."""
    n = len(worker)
    if n == 0:
        return []
    cut = np.zeros(n, dtype=bool)
    cut[0] = True
    cut[1:] = (worker[1:] != worker[:-1]) | (s[1:] != s_next[:-1])
    bounds = []
    starts = [*np.flatnonzero(cut).tolist(), n]
    for lo, hi in itertools.pairwise(starts):
        for a in range(lo, hi, episode_length):
            bounds.append((a, min(a + episode_length, hi)))
    return bounds


def check_dataset_id(dataset_id: str) -> tuple[str | None, str, int]:
    """``(namespace, name, version)`` of a Minari id, or :class:`ConfigError` naming it."""
    from minari.dataset.minari_dataset import parse_dataset_id

    if not isinstance(dataset_id, str) or "-v" not in dataset_id:
        raise ConfigError(f"malformed Minari id {dataset_id!r}", key="dataset_id",
                          fix="use [namespace/]name-v<version>, e.g. simlab/table-walk-v0")
    try:
        return parse_dataset_id(dataset_id)
    except (ValueError, TypeError):
        raise ConfigError(f"malformed Minari id {dataset_id!r}", key="dataset_id",
                          fix="use [namespace/]name-v<version>, e.g. simlab/table-walk-v0"
                          ) from None


@contextmanager
def _datasets_root(path: Path):
    """Point Minari's datasets root at ``path`` for the duration of the block."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def _env_spec(ds: Any, arena: str | None, goal: str | None, episode_length: int) -> Any:
    """The ``TableArenaStates-v0`` spec that reproduces the data's spaces and reward, or
    None (with a warning) when the arena cannot be loaded (e.g. a real robot's import:
    pass ``arena=``)."""
    import gymnasium as gym

    import simlab.envs  # noqa: F401  (registration)
    from simlab.physics.arena import load_arena

    m = ds.manifest
    try:
        load_arena(arena or m["arena"]["name"])
    except (ConfigError, OSError) as exc:
        warn(f"no env spec recorded (recover_environment() will not work): the arena "
             f"{arena or m['arena']['name']!r} does not load ({exc}); pass --arena "
             "NAME_OR_TOML")
        return None
    names = [g["name"] for g in m["arena"].get("goals", [])]
    kwargs: dict[str, Any] = {
        "states": np.asarray(ds.centres, dtype=float).tolist(),
        "arena": arena or m["arena"]["name"],
        "action_set": ds.action_set.to_json(),
        "pose_source": "odometry" if m.get("pose_source") == "odometry" else "truth",
    }
    if goal is not None or names:
        kwargs["goal"] = goal if goal is not None else names[0]
    base = gym.spec("simlab/TableArenaStates-v0")
    return gym.envs.registration.EnvSpec(
        id=base.id, entry_point=base.entry_point, max_episode_steps=int(episode_length),
        kwargs={**base.kwargs, **kwargs},
    )


@dataclass(frozen=True, kw_only=True)
class ExportMinariConfig(CommandConfig):
    """Options of ``simlab export-minari`` / :func:`export_minari`. The Minari id is the
    field ``dataset_id`` (``--id`` on the command line; ``dataset_id`` in a TOML file)."""

    COMMAND = "export-minari"
    ARGUMENTS = ("dataset", "dataset_id")

    dataset: Path = option(help="dataset directory written by `simlab collect`",
                           positional=True)
    dataset_id: str = option(help="Minari dataset id, e.g. simlab/table-walk-v0", flag="id")
    episode_length: int | None = option(None, "transitions per episode (default: the "
                                        "dataset's part size)")
    goal: str | None = option(None, "goal area name: reward 1 when s' is in it (default: "
                              "rewards 0)")
    author: str = option("simlab", "Minari metadata: author", cli=False)
    author_email: str = option("unknown", "Minari metadata: author's e-mail", cli=False)
    overwrite: bool = option(False, "replace a local Minari dataset with the same id")
    arena: Any | None = option(None, "arena (built-in name or TOML path) recorded in the env "
                               "spec for recover_environment() (default: the manifest's "
                               "arena name)")

    def validate(self) -> None:
        if self.arena is not None:
            from simlab.physics.arena import check_arena_option

            check_arena_option(self.arena)
        if self.episode_length is not None:
            validation.whole(self.episode_length, "episode_length", minimum=1)


@command(ExportMinariConfig)
def export_minari(cfg: ExportMinariConfig) -> MinariExportResult:
    """Write the dataset directory ``dataset`` as the Minari dataset ``dataset_id``.

    Takes an :class:`ExportMinariConfig` or its fields
    (``export_minari(dataset, dataset_id, episode_length=64)``):

    * ``dataset``: a directory written by ``simlab collect`` (validated on read).
    * ``dataset_id``: Minari id, ``[namespace/]name-v<version>`` (e.g.
      ``simlab/table-walk-v0``).
    * ``episode_length``: transitions per episode (default: the dataset's part size).
    * ``goal``: name of a goal area of the dataset's arena: reward 1 when s' is in it.
    * ``author``, ``author_email``: Minari metadata.
    * ``overwrite``: replace an existing local Minari dataset with this id.
    * ``arena``: arena (built-in name or TOML path) of the recorded env spec (default: the
      manifest's arena name).

    The dataset is stored where Minari keeps local datasets (``MINARI_DATASETS_PATH``
    or ``~/.minari/datasets``) in Minari's Arrow format.
    """
    try:
        import minari  # noqa: F401  (present? checked before any work)
        from gymnasium import spaces
    except ModuleNotFoundError:
        raise ConfigError("exporting to Minari needs minari", key="minari",
                          fix='pip install "simlab[minari]"') from None
    from minari.storage import get_dataset_path

    from simlab.data.dataset import open_dataset

    dataset_id, goal = cfg.dataset_id, cfg.goal
    check_dataset_id(dataset_id)
    ds = open_dataset(cfg.dataset, validate=True)
    ds.warn_if_incomplete("the Minari dataset")
    episode_length = cfg.episode_length
    if episode_length is None:  # the manifest's part size, checked like the option
        episode_length = validation.whole(int(ds.manifest["parameters"].get("part_size", 250)),
                                          "episode_length", minimum=1)
    if ds.table.num_rows == 0:
        raise ConfigError("the dataset has no transitions yet", path=ds.directory)
    reward_states = _goal_states(ds, goal)
    target = get_dataset_path(dataset_id)
    if target.exists() and not cfg.overwrite:
        raise ConfigError(f"a Minari dataset {dataset_id!r} already exists", path=target,
                          fix="choose another --id or pass --overwrite")
    episodes = _episodes(ds, reward_states, episode_length)
    _publish(dataset_id, target, episodes, dict(
        env=_env_spec(ds, cfg.arena, goal, episode_length),
        observation_space=spaces.Discrete(ds.n_states),
        action_space=spaces.Discrete(ds.n_actions),
        algorithm_name="epsilon-greedy, epsilon = 1 (uniform random actions)",
        author=cfg.author,
        author_email=cfg.author_email,
        code_permalink="simlab collect",
        description=_description(ds.manifest, goal),
        data_format="arrow",
    ))
    return MinariExportResult(
        dataset_id=dataset_id,
        episodes=len(episodes),
        steps=int(sum(len(e.actions) for e in episodes)),
        path=str(target),
    )


def _goal_states(ds: Any, goal: str | None) -> np.ndarray | None:
    """(S,) bool: the states of goal area ``goal`` of the dataset's arena (None: no goal)."""
    if goal is None:
        return None
    from simlab.data.goals import goal_state_masks, goals_from_manifest

    goals = goals_from_manifest(ds.manifest["arena"].get("goals", []))
    names, masks = goal_state_masks(goals, ds.centres)
    if goal not in names:
        raise ConfigError(f"unknown goal {goal!r}", key="goal",
                          fix=f"the dataset's arena has {', '.join(names)}")
    return masks[list(names).index(goal)]


def _episodes(ds: Any, reward_states: np.ndarray | None, episode_length: int) -> list[Any]:
    """The dataset's rows cut into Minari episode buffers (observations are states; the
    pose, blocked flag and clock ride in ``infos``; the last step of each is truncated)."""
    from minari.data_collector import EpisodeBuffer

    worker = ds.column("worker")
    s = ds.column("s").astype(np.int64)
    a = ds.column("a").astype(np.int64)
    s_next = ds.column("s_next").astype(np.int64)
    pose = np.stack([ds.column(c) for c in ("x", "y", "yaw")], axis=1)
    pose_next = np.stack([ds.column(c) for c in ("x_next", "y_next", "yaw_next")], axis=1)
    blocked = ds.column("blocked").astype(bool)
    t = ds.column("t")
    t_next = t + ds.column("duration")
    episodes: list[Any] = []
    for i, (lo, hi) in enumerate(_episode_bounds(worker, s, s_next, episode_length)):
        n = hi - lo
        rewards = (np.zeros(n) if reward_states is None
                   else reward_states[s_next[lo:hi]].astype(np.float64))
        truncations = np.zeros(n, dtype=bool)
        truncations[-1] = True
        episodes.append(EpisodeBuffer(
            id=i,
            observations=np.concatenate([s[lo:lo + 1], s_next[lo:hi]]),
            actions=a[lo:hi].copy(),
            rewards=rewards,
            terminations=np.zeros(n, dtype=bool),
            truncations=truncations,
            infos={
                "pose": np.concatenate([pose[lo:lo + 1], pose_next[lo:hi]]),
                "blocked": np.concatenate([[False], blocked[lo:hi]]).reshape(-1, 1),
                "t": np.concatenate([t[lo:lo + 1], t_next[lo:hi]]).reshape(-1, 1),
            },
        ))
    return episodes


def _description(m: dict[str, Any], goal: str | None) -> str:
    return (
        f"epsilon = 1 random walk of a TurtleBot3 Burger in the {m['arena']['name']!r} arena "
        f"({m.get('simulator', 'physics')} simulator, pose source {m['pose_source']}); "
        f"{m['discretizer']['n_states']} Voronoi states (discretizer "
        f"{str(m['discretizer']['hash'])[:12]}), 16 motion primitives (index = speed * 8 + "
        f"direction). Seed {m['seed']}, {m['workers']} workers. "
        + (f"Reward: 1 when s' is in goal {goal!r}." if goal else "Rewards are 0.")
    )


def _publish(dataset_id: str, target: Path, episodes: list[Any], meta: dict[str, Any]) -> None:
    """Create the Minari dataset in a temporary datasets root beside Minari's and move it
    into place only once it is complete (an existing one is replaced only then)."""
    import minari
    from filelock import FileLock
    from minari.namespace import create_namespace, list_local_namespaces
    from minari.storage import get_dataset_path

    namespace, _, _ = check_dataset_id(dataset_id)
    root = get_dataset_path()  # Minari's datasets root (created if missing)
    remove_dead_staging(root)
    tmp_root = Path(tempfile.mkdtemp(prefix=f".{root.name}{STAGING_INFIX}{os.getpid()}-",
                                     dir=root.parent))
    alive = FileLock(tmp_root / OWNER_LOCK)
    alive.acquire()  # held while this export lives (see remove_dead_staging)
    try:
        with warnings.catch_warnings(), _datasets_root(tmp_root):
            warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\..*")
            try:
                minari.create_dataset_from_buffers(dataset_id, episodes, **meta)
            except ValueError as exc:
                raise ConfigError(str(exc), key="dataset_id") from None
        if namespace is not None and namespace not in list_local_namespaces():
            create_namespace(namespace)
        target.parent.mkdir(parents=True, exist_ok=True)
        if target.exists():  # overwrite: set aside only once the new one is complete
            set_aside(target, tmp_root / PREVIOUS / target.relative_to(root))
        os.replace(tmp_root / dataset_id, target)
    finally:
        alive.release()
        _restore_previous(tmp_root, root)
        shutil.rmtree(tmp_root, ignore_errors=True)


#: Staging roots are ``.<datasets root name>.simlab-<pid>-XXXX`` beside Minari's datasets
#: root: the owner's process id, then mkdtemp's random part.
STAGING_INFIX = ".simlab-"
#: Where, inside a staging root, the dataset an export replaces waits (under its id's path)
#: until the new one is in place.
PREVIOUS = "previous"
#: The lock file inside a staging root that its export holds while it lives.
OWNER_LOCK = ".owner.lock"
#: Seconds a staging root whose owner's process id is in use (by the export, or by another
#: process that got the id after the export was killed) must be old before its lock alone
#: decides: an export holds its lock a moment after creating its root.
STAGING_GRACE_SECONDS = 30.0


def _pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (possibly another user's)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _dead_owner(stale: Path, prefix: str) -> bool:
    """Whether the export that made the staging root ``stale`` is gone: no process holds its
    lock, and its process no longer exists (or, when the id is in use again, the root is
    older than :data:`STAGING_GRACE_SECONDS`). Roots of an earlier layout (no process id in
    the name) count by age alone."""
    import time

    from filelock import FileLock, Timeout

    pid_text = stale.name[len(prefix):].split("-", 1)[0]
    age = time.time() - stale.stat().st_mtime
    if not pid_text.isdigit() or "-" not in stale.name[len(prefix):]:
        return age >= STAGING_GRACE_SECONDS
    if _pid_alive(int(pid_text)) and age < STAGING_GRACE_SECONDS:
        return False  # its export may be between creating the root and locking it
    lock = FileLock(stale / OWNER_LOCK)
    try:
        lock.acquire(timeout=0)
    except Timeout:
        return False  # a live export
    lock.release()
    return True


def _restore_previous(staging: Path, root: Path) -> None:
    """Put back the dataset an export set aside in ``staging`` (``previous/<id path>``) when
    nothing took its place: stopped between its two renames, it is the only copy."""
    previous = staging / PREVIOUS
    if not previous.is_dir():
        return
    for meta in sorted(previous.rglob("metadata.json")):  # listed before anything moves
        aside = meta.parent.parent  # <id>/data/metadata.json
        put_back(aside, root / aside.relative_to(previous))


def remove_dead_staging(root: Path) -> list[Path]:
    """Remove the staging roots beside Minari's datasets ``root`` that killed exports left
    (SIGKILL, power cut): only simlab's (``.<root>.simlab-<pid>-*`` directories of this
    user) and only those whose export is gone (:func:`_dead_owner`), so two exports never
    remove each other's. Returns those removed."""
    prefix = f".{root.name}{STAGING_INFIX}"
    removed = []
    for stale in root.parent.glob(f"{prefix}*"):
        try:
            if (stale.is_symlink() or not stale.is_dir() or stale.stat().st_uid != os.getuid()
                    or not _dead_owner(stale, prefix)):
                continue
        except OSError:
            continue
        _restore_previous(stale, root)
        shutil.rmtree(stale, ignore_errors=True)
        removed.append(stale)
    return removed
