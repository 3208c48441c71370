"""A real robot's pose log -> decisions (transitions) -> a simlab dataset.

**Log format.** Whitespace-separated text, one sample per line, ``#`` starts a comment::

    # t x y yaw [cell [n_cells]]
    0.0   1.20 0.40 0.00   7 38
    0.5   1.20 0.40 0.00   7 38

``t`` seconds (strictly increasing), ``x y`` metres and ``yaw`` radians in the map frame
(wrapped or counting whole turns: the dataset stores it in ``(-pi, pi]``,
:func:`stored_yaw`), optionally the robot's own state number ``cell`` and the number of
states ``n_cells``.
Every line has the same number of columns (4, 5 or 6). There is **no action column**: the
actions are inferred from the motion (about 2 Hz is enough).

``n_cells`` may grow along the log (0, 1, ..., 37, 38), as on a robot that builds its states
while it moves (Chartouny et al. 2024 build the Voronoi states online); it never shrinks,
and its last value is the log's number of states, the numbering of ``cell``. A sample whose
``cell`` is not yet below its ``n_cells`` was logged **before its state existed** (its cell
is a placeholder): with ``--use-cell-column`` the decisions that start or end at such a
sample are left out of the dataset and counted in the summary (no state can be given to
them); with the nearest centre of the states file every decision keeps its states.

**Segmentation** (:func:`segment_decisions`, a pure function of arrays so that other
importers, e.g. of ROS bags, reuse it). Each interval between two samples is labelled

* ``move`` when the robot translates faster than ``move_speed`` (m/s);
* otherwise ``turn`` when it rotates faster than ``turn_rate`` (rad/s);
* otherwise ``idle``.

A simlab-like primitive turns in place to its heading, then drives straight (or skips
the drive when blocked). So: every run of ``turn`` intervals starts a decision; a run of
``move`` intervals that follows a turn (directly or after an idle gap of at most
``join_gap`` s) ends that turn's decision; any other ``move`` run starts (and ends) a
decision of its own — a move not preceded by a rotation (the robot already faced the
heading). A decision without ``move`` is **blocked** (rotation without translation).

Limits stated, not hidden: a blocked attempt that needs no rotation leaves no trace in a
pose log and cannot be recovered; two decisions with no idle sample between them and no
rotation merge into one; a decision's start and end are known to one sample interval.

**Action** (:func:`decision_actions`): the heading octant of the decision's translation
(from the sample where the move starts to the last one), or of the final yaw when
blocked, numbered in the declared :class:`~simlab.base.actions.ActionSet` (``ccw-east`` for the
ISIR logs). With 16 actions the speed is ``fast`` when the mean translation speed exceeds
``speed_split`` (m/s); blocked decisions are taken as slow (the log cannot tell).

**States**: from the log's ``cell`` column (option) or the nearest centre of the states
file. With a cell column numbered as the file's states, the two are compared sample by
sample either way (:mod:`simlab.data.cellcheck`): a robot whose cells are not the file's
Voronoi cells is named, state by state, with where its labels put the centres.
:func:`import_log` writes the dataset with :func:`simlab.data.writer.write_dataset`
(pose source ``log``); ``simlab import-log`` is its command line, its options the fields of
:class:`ImportLogConfig`. The option groups :class:`SegmentOptions` (the thresholds) and
:class:`RobotActionOptions` (the log's action numbering) are shared with ``import-bag``.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import ActionSet, parse_action_set
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, command, option
from simlab.data.cellcheck import CellColumnCheck, check_cell_column

_MOVE, _TURN, _IDLE = 2, 1, 0


@dataclass(frozen=True)
class PoseLog:
    """Samples of a pose log, ``N`` rows.

    Attributes:
        t: ``(N,)`` s, strictly increasing.
        xy: ``(N, 2)`` m. yaw: ``(N,)`` rad.
        cell: ``(N,)`` int64 state numbers of the log, or None.
        n_cells: the log's number of states: the last ``n_cells`` (None when absent).
        n_cells_at: ``(N,)`` int64 number of states when each sample was logged
            (non-decreasing), or None.
        path: the file.
    """

    t: NDArray[np.float64]
    xy: NDArray[np.float64]
    yaw: NDArray[np.float64]
    cell: NDArray[np.int64] | None
    n_cells: int | None
    path: Path | None = None
    n_cells_at: NDArray[np.int64] | None = None

    def before_state(self) -> NDArray[np.bool_]:
        """``(N,)`` True where the sample's cell did not exist yet (``cell >= n_cells`` of
        its line); all False without the two columns."""
        if self.cell is None or self.n_cells_at is None:
            return np.zeros(len(self.t), dtype=bool)
        return self.cell >= self.n_cells_at


#: Largest magnitude of a log value but the time: 1e9 (m, rad, cells). A pose 1,000,000 km
#: away is a unit or parsing mistake, and beyond it the segmentation's squares overflow.
MAX_LOG_VALUE = 1e9

#: Largest magnitude of a log time (s): a robot's own log stamps in UNIX time (about 1.5e9 s
#: in the ISIR lab's logs; float64 keeps them to a microsecond); 1e11 s is over 3,000 years,
#: so a log in milliseconds (1.5e12) is refused with the unit named.
MAX_LOG_TIME = 1e11


def _number(token: str, path: Path, lineno: int, column: str, whole: bool) -> float:
    try:
        value = float(token)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or (whole and not value.is_integer()):
        kind = "a whole number" if whole else "a finite number"
        shown = token if len(token) <= 30 else f"{token[:20]}... ({len(token)} characters)"
        raise ConfigError(f"expected {kind}, got {shown!r}", path=path,
                          key=f"line {lineno}: {column}")
    limit = MAX_LOG_TIME if column == "t" else MAX_LOG_VALUE
    if abs(value) > limit:
        raise ConfigError(f"{value:g} is beyond +-{limit:g}", path=path,
                          key=f"line {lineno}: {column}",
                          fix="times in s, positions in m, yaw in rad")
    return value


def read_pose_log(path: str | os.PathLike[str]) -> PoseLog:
    """Read a pose log (see the module docstring). Raises ConfigError naming file and line."""
    path = Path(path)
    validation.existing_file(path, "log", what="pose log")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"byte {exc.start}: not UTF-8 text", path=path) from None
    names = ("t", "x", "y", "yaw", "cell", "n_cells")
    rows: list[list[float]] = []
    width = None
    for lineno, line in enumerate(text.splitlines(), start=1):
        tokens = line.split("#", 1)[0].split()
        if not tokens:
            continue
        if width is None:
            width = len(tokens)
            if width not in (4, 5, 6):
                raise ConfigError(f"expected 4 to 6 columns 't x y yaw [cell [n_cells]]', got "
                                  f"{width}", path=path, key=f"line {lineno}")
        if len(tokens) != width:
            raise ConfigError(f"expected {width} columns like the first line, got "
                              f"{len(tokens)}", path=path, key=f"line {lineno}")
        rows.append([_number(tok, path, lineno, names[j], whole=j >= 4)
                     for j, tok in enumerate(tokens)])
    if len(rows) < 2:
        raise ConfigError(f"{len(rows)} sample(s); a log needs at least 2", path=path)
    data = np.asarray(rows, dtype=np.float64)
    t = data[:, 0]
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        raise ConfigError(f"time does not increase at sample {back[0] + 2} ({t[back[0]]:g} -> "
                          f"{t[back[0] + 1]:g})", path=path, key="t")
    cell = data[:, 4].astype(np.int64) if width >= 5 else None  # type: ignore[operator]
    if cell is not None and cell.min() < 0:
        raise ConfigError(f"negative cell {cell.min()} at sample {int(cell.argmin()) + 1}",
                          path=path, key="cell", fix="cells are numbered from 0")
    n_cells, n_cells_at = None, None
    if width == 6:
        n_cells_at = data[:, 5].astype(np.int64)
        if n_cells_at.min() < 0:
            k = int(np.argmin(n_cells_at))
            raise ConfigError(f"negative n_cells {n_cells_at[k]} at sample {k + 1}",
                              path=path, key="n_cells",
                              fix="n_cells counts the states built so far (0 or more)")
        down = np.flatnonzero(np.diff(n_cells_at) < 0)
        if down.size:
            k = int(down[0])
            raise ConfigError(f"n_cells decreases at sample {k + 2} ({n_cells_at[k]} -> "
                              f"{n_cells_at[k + 1]}); it may only grow as states are built",
                              path=path, key="n_cells")
        n_cells = int(n_cells_at[-1])
        if n_cells < 1:
            raise ConfigError("n_cells is 0 on every line: no state was ever built",
                              path=path, key="n_cells")
        if cell is not None and cell.max() >= n_cells:
            raise ConfigError(f"cell values {cell.min()}..{cell.max()} outside 0..{n_cells - 1}",
                              path=path, key="cell")
    return PoseLog(t=t, xy=data[:, 1:3].copy(), yaw=data[:, 3].copy(), cell=cell,
                   n_cells=n_cells, path=path, n_cells_at=n_cells_at)


@dataclass(frozen=True)
class SegmentParams:
    """Thresholds of :func:`segment_decisions`.

    Attributes:
        move_speed: m/s; an interval faster than this translates (default 0.04, well
            below simlab's slow 0.10 m/s and above ~1 cm of pose noise at 2 Hz).
        turn_rate: rad/s; an interval not translating but turning faster than this is a
            rotation (default 0.3).
        join_gap: s; longest idle gap between a rotation and the move that completes its
            decision (default 1.0: two samples at 2 Hz).
        speed_split: m/s; 16-action sets only: faster mean translation = fast primitive
            (default 0.16, between simlab's 0.10 and 0.22).
    """

    move_speed: float = 0.04
    turn_rate: float = 0.3
    join_gap: float = 1.0
    speed_split: float = 0.16

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            validation.positive(value, name, allow_zero=True)
        for name in ("move_speed", "turn_rate"):  # at 0, pose noise would be motion
            if getattr(self, name) <= 0:
                raise ConfigError(f"must be > 0, got {getattr(self, name)!r}", key=name)


@dataclass(frozen=True, kw_only=True)
class SegmentOptions(CommandConfig):
    """The segmentation-threshold field group of ``import-log`` and ``import-bag``
    (``--move-speed``, ``--turn-rate``, ``--join-gap``, ``--speed-split``): inherit it in a
    command's config and call :meth:`segment_params`. Defaults and checks are
    :class:`SegmentParams`'s, so the thresholds are spelled once, there."""

    move_speed: float = option(SegmentParams.move_speed,
                               "translation faster than this is a move", metavar="M/S")
    turn_rate: float = option(SegmentParams.turn_rate, "rotation faster than this is a turn",
                              metavar="RAD/S")
    join_gap: float = option(SegmentParams.join_gap,
                             "longest pause between a turn and its move", metavar="S")
    speed_split: float = option(SegmentParams.speed_split,
                                "16 actions: faster mean translation = fast primitive",
                                metavar="M/S")

    def validate(self) -> None:
        super().validate()
        self.segment_params()  # a bad threshold names its field here

    def segment_params(self) -> SegmentParams:
        """The :class:`SegmentParams` of the group's fields."""
        return SegmentParams(**{f.name: getattr(self, f.name) for f in fields(SegmentParams)})


@dataclass(frozen=True, kw_only=True)
class RobotActionOptions(CommandConfig):
    """The ``--n-actions/--convention`` field group of the robot-data importers
    (``import-log``, ``import-bag``): the action set the imported decisions are numbered in.

    Not :class:`~simlab.base.actions.ActionSetOptions`: its defaults are simlab's own robot (16
    actions, ``simlab`` order, ``n_actions`` None = not given, plus ``--speed``), these are
    the ISIR robot's logs (8 actions counted ``ccw-east``), and the importers never had a
    speed option (an 8-action import is ``slow``).
    """

    n_actions: int = option(8, "number of actions of the robot", choices=(8, 16))
    convention: str = option("ccw-east", "direction numbering: simlab, ccw-east (the ISIR "
                             "robot's) or 8 comma-separated numbers")

    def validate(self) -> None:
        super().validate()
        self.make_action_set()  # a bad convention names its field here

    def make_action_set(self) -> ActionSet:
        """The :class:`~simlab.base.actions.ActionSet` of the fields."""
        return parse_action_set(self.n_actions, self.convention)


@dataclass(frozen=True)
class Decisions:
    """Decisions found in a pose sequence, ``K`` rows, as sample indices.

    Attributes:
        start: ``(K,)`` sample before the decision's first motion.
        end: ``(K,)`` sample after its last motion.
        move_start: ``(K,)`` sample where the translation starts (``end`` if blocked).
        blocked: ``(K,)`` bool, no translation.
        heading: ``(K,)`` rad, direction of the translation (final yaw if blocked).
        speed: ``(K,)`` m/s, mean translation speed (0 if blocked).
    """

    start: NDArray[np.int64]
    end: NDArray[np.int64]
    move_start: NDArray[np.int64]
    blocked: NDArray[np.bool_]
    heading: NDArray[np.float64]
    speed: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.start)


def wrap_angle(a: Any) -> NDArray[np.float64]:
    """Angles wrapped to ``[-pi, pi)`` (rad)."""
    return (np.asarray(a, dtype=np.float64) + math.pi) % (2 * math.pi) - math.pi


def stored_yaw(yaw: Any) -> NDArray[np.float64]:
    """Yaws ``(N,)`` (rad) as a dataset stores them: in ``(-pi, pi]``, the range of the
    ``atan2`` of a pose message's quaternion, so that a log's dataset and the same log
    through a ROS bag agree bit for bit. A robot's log may unwrap its yaw (the ISIR logs
    count whole turns); values already in range are kept as they are (``(a + pi) % 2pi
    - pi`` would move them by an ulp), the others are wrapped."""
    a = np.asarray(yaw, dtype=np.float64)
    inside = (a > -math.pi) & (a <= math.pi)
    return np.where(inside, a, -wrap_angle(-a))


def interval_labels(t: Any, xy: Any, yaw: Any, params: SegmentParams) -> NDArray[np.int8]:
    """``(N-1,)`` label of each sample interval: 2 move, 1 turn, 0 idle."""
    t = np.asarray(t, dtype=np.float64)
    dt = np.diff(t)
    speed = np.linalg.norm(np.diff(np.asarray(xy, dtype=np.float64), axis=0), axis=1) / dt
    rate = np.abs(wrap_angle(np.diff(np.asarray(yaw, dtype=np.float64)))) / dt
    return np.where(speed > params.move_speed, _MOVE,
                    np.where(rate > params.turn_rate, _TURN, _IDLE)).astype(np.int8)


def _runs(labels: NDArray[np.int8]) -> list[tuple[int, int, int]]:
    """``(label, first sample, last sample)`` of each run of equal interval labels."""
    if labels.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate([[0], cuts])
    stops = np.concatenate([cuts, [labels.size]])
    return [(int(labels[a]), int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def segment_decisions(t: Any, xy: Any, yaw: Any,
                      params: SegmentParams | None = None) -> Decisions:
    """Cut a pose sequence into decisions (rules in the module docstring).

    Args:
        t: ``(N,)`` s, strictly increasing. xy: ``(N, 2)`` m. yaw: ``(N,)`` rad.
        params: thresholds (defaults of :class:`SegmentParams`).
    """
    params = SegmentParams() if params is None else params
    t = np.asarray(t, dtype=np.float64)
    xy = np.asarray(xy, dtype=np.float64)
    yaw = np.asarray(yaw, dtype=np.float64)
    if xy.shape != (len(t), 2) or yaw.shape != t.shape:
        raise ConfigError(f"expected t (N,), xy (N, 2), yaw (N,); got {t.shape}, {xy.shape}, "
                          f"{yaw.shape}", key="poses")
    if np.any(np.diff(t) <= 0) or not (np.all(np.isfinite(xy)) and np.all(np.isfinite(yaw))):
        raise ConfigError("times must increase strictly and poses be finite", key="poses")
    found: list[list[int]] = []  # [start, end, move_start or -1]
    for label, first, last in _runs(interval_labels(t, xy, yaw, params)):
        if label == _TURN:
            found.append([first, last, -1])
        elif label == _MOVE:
            prev = found[-1] if found else None
            if prev is not None and prev[2] < 0 and t[first] - t[prev[1]] <= params.join_gap:
                prev[1], prev[2] = last, first
            else:
                found.append([first, last, first])
    arr = np.asarray(found, dtype=np.int64).reshape(-1, 3)
    start, end, move = arr[:, 0], arr[:, 1], arr[:, 2]
    blocked = move < 0
    move = np.where(blocked, end, move)
    delta = xy[end] - xy[move]
    heading = np.where(blocked, yaw[end], np.arctan2(delta[:, 1], delta[:, 0]))
    span = np.where(blocked, 1.0, t[end] - t[move])
    speed = np.where(blocked, 0.0, np.linalg.norm(delta, axis=1) / span)
    return Decisions(start=start, end=end, move_start=move, blocked=blocked,
                     heading=wrap_angle(heading), speed=speed)


def decision_actions(decisions: Decisions, action_set: ActionSet,
                     params: SegmentParams | None = None) -> NDArray[np.int64]:
    """``(K,)`` action of each decision in ``action_set``: nearest heading octant (and, for
    16 actions, the speed class by ``params.speed_split``)."""
    params = SegmentParams() if params is None else params
    headings = action_set.headings()
    gap = np.abs(wrap_angle(decisions.heading[:, None] - headings[None, :]))
    if action_set.n_actions == 16:
        fast = (decisions.speed > params.speed_split) & ~decisions.blocked
        gap[:, :8] += np.where(fast, 10.0, 0.0)[:, None]
        gap[:, 8:] += np.where(fast, 0.0, 10.0)[:, None]
    return np.argmin(gap, axis=1).astype(np.int64)


@dataclass(frozen=True)
class ImportLogResult:
    """What :func:`import_log` found and wrote."""

    out: Path
    samples: int
    decisions: int
    blocked: int
    actions: NDArray[np.int64]
    action_set: ActionSet
    state_source: str
    off_map: int = 0
    cell_check: CellColumnCheck | None = None
    """The log's cell column against the nearest centre of the states file
    (:func:`simlab.data.cellcheck.check_cell_column`), when the log has one numbered as the
    states file's states; None otherwise."""
    before_state: int = 0
    """Decisions left out: they start or end at a sample logged before its state existed
    (``--use-cell-column`` with a growing ``n_cells``)."""


def _log_states(log: PoseLog, dec: Decisions, disc: Any, use_cell_column: bool
                ) -> tuple[Any, Any, str]:
    if not use_cell_column:
        return None, None, "nearest centre of the states file"
    if log.cell is None:
        raise ConfigError("--use-cell-column: the log has no cell column (t x y yaw only)",
                          path=log.path, key="cell")
    if log.n_cells is not None and log.n_cells != int(disc.n_states):
        raise ConfigError(f"the log has {log.n_cells} cells, the states file "
                          f"{disc.n_states} states", path=log.path, key="n_cells")
    if log.cell.max() >= int(disc.n_states):
        k = int(log.cell.argmax())
        raise ConfigError(f"cell {log.cell[k]} at sample {k + 1} is not a state of the states "
                          f"file (0..{int(disc.n_states) - 1})", path=log.path, key="cell",
                          fix="use the states file the robot numbered its cells with")
    return log.cell[dec.start], log.cell[dec.end], "cell column of the log"


def _cell_check(log: PoseLog, disc: Any) -> CellColumnCheck | None:
    """The cell column against the states file, on the samples logged after their state
    existed; None without a cell column or when it numbers other states than the file's."""
    n = int(disc.n_states)
    if log.cell is None or (log.n_cells is not None and log.n_cells != n) or \
            int(log.cell.max()) >= n:
        return None
    keep = ~log.before_state()
    if not keep.any() or n < 2:
        return None
    return check_cell_column(log.xy[keep], log.cell[keep],
                             np.asarray(disc.centres, dtype=np.float64),
                             n_existing=None if log.n_cells_at is None else
                             np.minimum(log.n_cells_at[keep], n))


#: Largest share of pose samples allowed off the map's free pixels (see :func:`import_log`).
MAX_OFF_MAP_FRACTION = 0.05


def _check_poses(log: PoseLog, map_path: str | os.PathLike[str], flip_y: bool) -> int:
    """Number of samples off free pixels; ConfigError (listing them) above the limit."""
    from discretize.mapcheck import check_points
    from discretize.mapio import read_map

    check = check_points(read_map(map_path, flip_y=flip_y), log.xy, what="pose sample")
    if check.bad.size > MAX_OFF_MAP_FRACTION * len(log.xy) or check.flip_suggested:
        raise ConfigError(_off_map(check), path=log.path, key="poses",
                          fix="the map image is probably stored bottom row first: try "
                          "--flip-y" if check.flip_suggested else
                          "poses must be in the map's frame, in metres")
    return int(check.bad.size)


def _off_map(check: Any) -> str:
    """One short line for the pose samples off the map's free pixels: how many, of which
    kind, the first one (a log has thousands of samples: they are not listed)."""
    bad = check.bad
    kinds = np.bincount(check.status[bad], minlength=4)
    parts = [f"{kinds[i]} {word}" for i, word in
             ((1, "on occupied pixels"), (2, "on unknown pixels"), (3, "outside the map"))
             if kinds[i]]
    k = int(bad[0])
    text = (f"{bad.size} of {len(check.xy)} pose samples are not on free pixels of the map "
            f"({', '.join(parts)}; the first: sample {k + 1} at ({check.xy[k, 0]:.4g}, "
            f"{check.xy[k, 1]:.4g}))")
    if check.flip_suggested:
        text += (f"; {int(check.free_if_flipped[bad].sum())} of them are free on the map "
                 "image flipped vertically")
    return text


def _check_near_centres(log: PoseLog, centres: NDArray[np.float64]) -> None:
    """Without a map, the states file is the only frame to check the poses against: more
    than :data:`MAX_OFF_MAP_FRACTION` of the samples farther from every centre than twice the
    widest gap between neighbouring centres (at least 1 m) means another frame or unit."""
    from scipy.spatial import cKDTree

    if len(centres) < 1:
        return
    tree = cKDTree(centres)
    gap = float(tree.query(centres, k=2)[0][:, 1].max()) if len(centres) > 1 else 0.0
    limit = max(1.0, 2.0 * gap)
    dist = tree.query(log.xy)[0]
    far = np.flatnonzero(dist > limit)
    if far.size > MAX_OFF_MAP_FRACTION * len(log.xy):
        k = int(far[0])
        raise ConfigError(f"{far.size} of {len(log.xy)} pose samples are more than {limit:.2f} "
                          f"m from every state centre (first: sample {k + 1} at "
                          f"({log.xy[k, 0]:.6g}, {log.xy[k, 1]:.6g}), {dist[k]:.4g} m away)",
                          path=log.path, key="poses", fix="poses and the states file must be "
                          "in the same frame, in metres (--map checks them against the map)")


@dataclass(frozen=True, kw_only=True)
class ImportLogConfig(RobotActionOptions, SegmentOptions):
    """Options of ``simlab import-log`` / :func:`import_log` (the groups:
    :class:`RobotActionOptions`, :class:`SegmentOptions`)."""

    COMMAND = "import-log"
    ARGUMENTS = ("log",)

    log: Path = option(help="pose log: whitespace text 't x y yaw [cell [n_cells]]', '#' "
                       "comments", positional=True)
    states: Any = option(help="states: `simlab discretize` JSON or centres text ('x y' or "
                         "'id x y theta' lines; from Python also a discretizer)")
    out: Path = option(help="dataset directory to write")
    use_cell_column: bool = option(False, "states from the log's cell column (default: "
                                   "nearest centre)")
    map: Any | None = option(None, "map_server map to check the poses against (default: no "
                             "check)", metavar="YAML")
    flip_y: bool = option(False, "flip the --map image vertically (stored bottom row first)")
    overwrite: bool = option(False, "replace a dataset in --out")


@command(ImportLogConfig)
def import_log(cfg: ImportLogConfig) -> ImportLogResult:
    """``simlab import-log``: a pose log -> a simlab dataset (pose source ``log``).

    Takes an :class:`ImportLogConfig` or its fields (``import_log(log, states=..., out=...)``):

    * ``log``: pose-log text file (module docstring).
    * ``states``: states file (``simlab discretize`` JSON, or centres text ``x y`` /
      ``id x y theta``) or a discretizer object.
    * ``out``: dataset directory to write.
    * ``n_actions``: 8 or 16. ``convention``: ``simlab``, ``ccw-east`` or 8 numbers.
    * ``use_cell_column``: states from the log's ``cell`` column instead of the centres.
    * ``move_speed``, ``turn_rate``, ``join_gap``, ``speed_split``: thresholds
      (:class:`SegmentParams`).
    * ``overwrite``: replace a dataset in ``out``.
    * ``map``: map_server YAML to check the poses against (optional). Every sample off
      free pixels is counted; more than :data:`MAX_OFF_MAP_FRACTION` of them is
      refused, listing them (and suggesting ``--flip-y`` when the flipped image
      frees most); fewer are recorded in the provenance (SLAM poses brush walls).
    * ``flip_y``: flip the map image vertically first.
    """
    from discretize.voronoi import load_states
    from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset

    log, states = cfg.log, cfg.states
    aset = cfg.make_action_set()
    segment = cfg.segment_params()
    disc = load_states(states) if isinstance(states, str | os.PathLike) else states
    plog = read_pose_log(log)
    dec = segment_decisions(plog.t, plog.xy, plog.yaw, segment)
    if len(dec) == 0:
        raise ConfigError("no motion found in the log (nothing turns or moves faster than "
                          "the thresholds)", path=plog.path, fix="check the units or lower "
                          "--move-speed / --turn-rate")
    off_map = 0 if cfg.map is None else _check_poses(plog, cfg.map, cfg.flip_y)
    if cfg.map is None:
        _check_near_centres(plog, np.asarray(disc.centres, dtype=np.float64))
    before = 0
    if cfg.use_cell_column:
        early = plog.before_state()
        keep = ~(early[dec.start] | early[dec.end])
        before = int((~keep).sum())
        if not keep.any():
            raise ConfigError(f"all {len(dec)} decisions start or end before their state "
                              "existed (cell >= n_cells on their lines)", path=plog.path,
                              key="cell", fix="import without --use-cell-column (states "
                              "from the nearest centre)")
        dec = Decisions(**{f.name: getattr(dec, f.name)[keep] for f in fields(Decisions)})
    s, s2, source = _log_states(plog, dec, disc, cfg.use_cell_column)
    cell_check = _cell_check(plog, disc)
    actions = decision_actions(dec, aset, segment)
    pose = np.column_stack([plog.xy, stored_yaw(plog.yaw)])
    walk = TransitionArrays(t=plog.t[dec.start], a=actions, pose=pose[dec.start],
                            pose_next=pose[dec.end], blocked=dec.blocked,
                            duration=plog.t[dec.end] - plog.t[dec.start], s=s, s_next=s2)
    info = DatasetInfo(
        discretizer=disc, action_set=aset, pose_source="log",
        provenance={"importer": "simlab import-log", "log": str(plog.path),
                    "states": str(states) if isinstance(states, str | os.PathLike) else None,
                    "samples": len(plog.t), "state_source": source,
                    "map": None if cfg.map is None else str(cfg.map), "flip_y": cfg.flip_y,
                    "samples_off_free_map": off_map,
                    "decisions_before_their_state": before,
                    "cell_column_check": None if cell_check is None else cell_check.to_dict(),
                    "segmentation": asdict(segment)},
        arena={"name": Path(log).stem, "file": None, "bounds": None, "goals": []},
        parameters={"importer": "pose-log"})
    res = write_dataset(cfg.out, walk, info, overwrite=cfg.overwrite)
    return ImportLogResult(out=res.out, samples=len(plog.t), decisions=len(dec),
                           blocked=int(dec.blocked.sum()), actions=actions, action_set=aset,
                           state_source=source, off_map=off_map, before_state=before,
                           cell_check=cell_check)
