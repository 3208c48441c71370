"""The robot's own cell labels against the states file: does the twin cut the lab where the
robot did?

A pose log with a ``cell`` column says which state the robot itself gave each pose. The twin
gives a pose the state of the nearest centre of the states file. Where the two disagree, the
robot's cells are not the file's Voronoi cells: the file may be another version than the one
the robot ran with, or a centre may have been moved or rebuilt since. A twin cut along the
file's boundaries then counts the robot's moves and stays in cells of another shape.

:func:`check_cell_column` measures the agreement sample by sample and, for the states that
disagree most, where a centre would have to sit for its labels to agree: each is moved alone
over a grid around its place (the others held where they are, those already moved included)
to the position where most samples agree. A state whose best position lies on the edge of
the searched square has labels that no centre near its own explains (cells split in time,
a state built late in a log without ``n_cells``, a hand-edited map): it is named, not moved.

A robot that builds its states as it moves (its log's ``n_cells`` grows) numbers them in
that order, and before a state is built its area carries its neighbours' labels: each sample
is compared with the nearest of the states built when it was logged.

Measured on the ISIR robot's pose log of 2018-06-15 (``poseCell_log20180615-112601.dat``,
2.2 hours, 15,424 samples, state 37 built after 81 % of them) against the published
centres: 98.5 % agree (95.8 % if every state is taken as built from the start); moving state
21's centre 0.20 m north and state 5's 0.10 m west makes every sample agree.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.errors import ConfigError

#: Half-width (m) of the square searched around a centre.
REACH = 0.3
#: Grid step (m) of that search.
STEP = 0.02
#: A state is searched when at least this share of its samples (labelled it, or nearest to
#: it) disagree, and at least :data:`MIN_SAMPLES` of them.
MIN_SHARE = 0.05
MIN_SAMPLES = 10


@dataclass(frozen=True)
class CentreFit:
    """One state whose labels disagree with the nearest centre."""

    state: int
    centre: tuple[float, float]
    """Its centre in the states file (m)."""
    samples: int
    """Samples that the robot labelled with this state or that are nearest its centre."""
    disagree: int
    """Of those, the samples whose label is not the nearest centre."""
    fitted: tuple[float, float] | None
    """Where the centre agrees best with the robot's labels (m), or None when the best
    place is on the edge of the searched square (no centre near its own explains them) or
    no move raises the agreement."""

    @property
    def shift(self) -> tuple[float, float] | None:
        if self.fitted is None:
            return None
        return (self.fitted[0] - self.centre[0], self.fitted[1] - self.centre[1])

    def to_dict(self) -> dict[str, Any]:
        return {"state": self.state, "centre": list(self.centre), "samples": self.samples,
                "disagree": self.disagree,
                "fitted": None if self.fitted is None else list(self.fitted)}


@dataclass(frozen=True)
class CellColumnCheck:
    """:func:`check_cell_column`'s answer."""

    samples: int
    agreement: float
    """Share of the samples whose label is the nearest centre of the states file."""
    agreement_fitted: float
    """The same share with every fitted centre moved to its fitted place."""
    states: tuple[CentreFit, ...]
    """The states searched, most disagreeing first."""
    reach: float = REACH
    """Half-width (m) of the square searched around each centre."""

    def lines(self) -> list[str]:
        """What ``simlab import-log`` prints: the agreement, then one line per state."""
        out = [f"the log's cell column agrees with the nearest centre of the states file in "
               f"{100 * self.agreement:.1f} % of {self.samples} samples"]
        moved = [f for f in self.states if f.fitted is not None]
        for f in self.states:
            share = f"{f.disagree} of its {f.samples} samples disagree"
            if f.fitted is None:
                out.append(f"  state {f.state}: {share}; its labels fit no centre within "
                           f"{self.reach:.2f} m of ({f.centre[0]:.3f}, {f.centre[1]:.3f})")
            else:
                (fx, fy), (cx, cy) = f.fitted, f.centre
                out.append(f"  state {f.state}: {share}; the labels put its centre at "
                           f"({fx:.3f}, {fy:.3f}), {fx - cx:+.2f} m in x and "
                           f"{fy - cy:+.2f} m in y from the file's")
        if moved:
            names = ", ".join(str(f.state) for f in moved)
            out.append(f"  with the centre{'s' if len(moved) > 1 else ''} of {names} moved "
                       f"there {100 * self.agreement_fitted:.1f} % agree: the robot's cells "
                       "are not the states file's there (another version of the file?)")
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"samples": self.samples, "agreement": self.agreement, "reach": self.reach,
                "agreement_fitted": self.agreement_fitted,
                "states": [f.to_dict() for f in self.states]}


def _labels(d: NDArray[np.float64]) -> NDArray[np.int64]:
    return np.argmin(d, axis=1).astype(np.int64)


def _worst_state(near: NDArray[np.int64], lab: NDArray[np.int64], S: int,
                 skip: NDArray[np.bool_], done: set[int], min_share: float, min_samples: int
                 ) -> tuple[int, int, int] | None:
    """The state that disagrees most (lowest index on ties) among those not ``done``, with
    at least ``min_samples`` and ``min_share`` of its samples disagreeing, the samples
    ``skip`` left out: ``(state, its samples, its disagreeing samples)``, or None."""
    bad = (near != lab) & ~skip
    # a state's samples: those labelled with it, and those nearest it labelled otherwise
    nearest_bad = np.bincount(near[bad], minlength=S)
    involved = np.bincount(lab, minlength=S) + nearest_bad
    wrong = np.bincount(lab[bad], minlength=S) + nearest_bad
    for s in np.lexsort((np.arange(S), -wrong)):
        s = int(s)
        if s not in done and wrong[s] >= min_samples and wrong[s] >= min_share * involved[s]:
            return s, int(involved[s]), int(wrong[s])
    return None


def _best_place(d: NDArray[np.float64], lab: NDArray[np.int64], pick: int,
                dist: Callable[[int, NDArray[np.float64], NDArray[np.intp]],
                               NDArray[np.float64]],
                centre: NDArray[np.float64], offsets: NDArray[np.floating[Any]], reach: float
                ) -> tuple[int, int, int]:
    """Centre ``pick`` moved alone over the grid ``centre + offsets x offsets``: the most
    samples that agree and the grid indices ``(i, j)`` of the first place reaching it (the
    middle when no move beats the place it is at). ``d`` the samples' distances to every
    centre, ``dist(pick, at, rows)`` the distances of the samples ``rows`` to ``pick`` at
    ``at``."""
    others = d.copy()
    others[:, pick] = np.inf
    o_arg, o_min = _labels(others), others.min(axis=1)
    # only samples the moved centre can reach change label: search on those alone
    reachable = d[:, pick] - reach * np.sqrt(2.0) <= o_min
    fixed = int(np.sum(o_arg[~reachable] == lab[~reachable]))
    rows = np.flatnonzero(reachable)
    q_arg, q_min, q_lab = o_arg[rows], o_min[rows], lab[rows]
    mid = len(offsets) // 2
    best = (int(np.sum(_labels(d) == lab)), mid, mid)
    for i, dx in enumerate(offsets):
        for j, dy in enumerate(offsets):
            dk = dist(pick, centre + np.array([dx, dy]), rows)
            # ties go to the lower index, as the nearest-centre rule breaks them
            mine = (dk < q_min) | ((dk == q_min) & (pick < q_arg))
            score = fixed + int(np.sum(np.where(mine, pick, q_arg) == q_lab))
            if score > best[0]:
                best = (score, i, j)
    return best


def check_cell_column(xy: ArrayLike, cell: ArrayLike, centres: ArrayLike, *,
                      n_existing: ArrayLike | None = None, max_states: int = 5,
                      reach: float = REACH, step: float = STEP,
                      min_share: float = MIN_SHARE, min_samples: int = MIN_SAMPLES
                      ) -> CellColumnCheck:
    """Agreement of the robot's labels ``cell`` ``(N,)`` of the poses ``xy`` ``(N, 2)`` (m)
    with the nearest of ``centres`` ``(S, 2)``, and where the ``max_states`` most disagreeing
    states' centres would have to sit (module docstring). Deterministic.

    ``n_existing`` ``(N,)``: the number of states built when each sample was logged, on a
    robot that builds its states as it moves and numbers them in that order (the log's
    ``n_cells``): a sample is compared with the nearest of the states that existed then
    (before a state is built, its area is its neighbours'). None: every state, always."""
    p = np.asarray(xy, dtype=np.float64)
    lab = np.asarray(cell)
    c = np.array(centres, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or lab.shape != (len(p),) or len(p) == 0:
        raise ConfigError(f"expected xy (N, 2) and cell (N,) with N > 0, got {p.shape} and "
                          f"{lab.shape}", key="cell")
    if c.ndim != 2 or c.shape[1] != 2 or len(c) < 2:
        raise ConfigError(f"expected at least 2 centres (S, 2), got {c.shape}", key="centres")
    lab = lab.astype(np.int64)
    if lab.min() < 0 or lab.max() >= len(c):
        raise ConfigError(f"cell values {lab.min()}..{lab.max()} are not states of the "
                          f"states file (0..{len(c) - 1})", key="cell")
    if not (reach > 0 and 0 < step <= reach):
        raise ConfigError(f"need 0 < step <= reach, got step {step}, reach {reach}")
    if n_existing is None:
        exists = np.ones((len(p), len(c)), dtype=bool)
    else:
        n_at = np.asarray(n_existing).astype(np.int64)
        if n_at.shape != (len(p),):
            raise ConfigError(f"expected n_existing (N,) = ({len(p)},), got {n_at.shape}",
                              key="n_cells")
        if np.any(lab >= n_at):
            k = int(np.argmax(lab >= n_at))
            raise ConfigError(f"sample {k + 1} is labelled {lab[k]} while only {n_at[k]} "
                              "states existed: leave out the samples logged before their "
                              "state", key="cell")
        exists = np.arange(len(c))[None, :] < n_at[:, None]

    def dist(k: int, at: NDArray[np.float64], rows: Any = slice(None)) -> NDArray[np.float64]:
        # distances of the samples ``rows`` to centre ``k`` placed at ``at``; inf where the
        # state did not exist yet
        q = p[rows]
        return np.where(exists[rows, k], np.hypot(q[:, 0] - at[0], q[:, 1] - at[1]), np.inf)

    d = np.column_stack([dist(k, c[k]) for k in range(len(c))])
    agreement = float(np.mean(_labels(d) == lab))
    k = round(reach / step)
    offsets = step * np.arange(-k, k + 1)
    fits: list[CentreFit] = []
    done: set[int] = set()
    # samples of a state no centre explains leave the ranking: its neighbours' disagreements
    # with it say nothing of their own centres
    unexplained = np.zeros(len(p), dtype=bool)
    for _ in range(max_states):
        near = _labels(d)
        worst = _worst_state(near, lab, len(c), unexplained, done, min_share, min_samples)
        if worst is None:
            break
        pick, samples, disagree = worst
        done.add(pick)
        score, i, j = _best_place(d, lab, pick, dist, c[pick].copy(), offsets, reach)
        centre = (float(c[pick, 0]), float(c[pick, 1]))
        on_edge = i in (0, 2 * k) or j in (0, 2 * k)
        fitted = None
        if score > int(np.sum(near == lab)) and not on_edge:
            c[pick] += (offsets[i], offsets[j])
            d[:, pick] = dist(pick, c[pick])
            fitted = (float(c[pick, 0]), float(c[pick, 1]))
        else:
            unexplained |= (lab == pick) | (near == pick)
        fits.append(CentreFit(state=pick, centre=centre, samples=samples, disagree=disagree,
                              fitted=fitted))
    return CellColumnCheck(samples=len(p), agreement=agreement,
                           agreement_fitted=float(np.mean(_labels(d) == lab)),
                           states=tuple(fits), reach=float(reach))
