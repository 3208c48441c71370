"""Dynamics of the three Visit-the-lab modules as numba kernels (thesis 2.1.1-2.1.3).

These functions are the single source of truth for the simulation: the Gymnasium
envs (:mod:`simlab.visitlab.envs`) and the fused training loops
(:mod:`simlab.visitlab.fused`) both call them. Everything is a plain array:

* ``st`` — the world state, int64 shape ``(N_STATE,)``, indexed by the ``S_*``
  constants: robot cell, robot orientation, human cell, human orientation,
  engagement (0 = not engaged, else the interaction level 5, 6 or 7), required
  direction, navigation goal label, and the direction the human moved during the
  last step (``-1``: did not move).
* walls ``walls_h``/``walls_v`` and the line-of-sight table ``los`` of a
  :class:`~simlab.visitlab.grid.Layout`; perception parameters ``pcfg``
  (:meth:`~simlab.visitlab.perception.Perception.to_array`); human parameters ``hp``
  (:meth:`~simlab.visitlab.humans.Human.to_array`).
* ``rng`` — a ``numpy.random.Generator`` (numba draws from the same stream, so a
  kernel and Python code sharing a generator stay in step).

Social step (:func:`social_step`), in this order — every interaction-level change
depends only on the state the robot observed and its action:

1. Percepts of the observed state: percept level 0-4, distance class, angle.
   "Appropriate distance" means class 1-3.
2. Attention: an engaged human (level >= 5) disengages when the distance is not
   appropriate, or with probability L_H (one draw per engaged step); the level
   falls back to the percept level.
3. Social actions. HELLO at level 3 or 4 with an appropriate distance -> 5; at level
   3 it fails with probability F_H (one draw), at level 4 it always succeeds. COME at
   5 -> 7 with probability 1 - P_H, else 6 (one draw). POINTING at 6 -> 7. Any other
   use of a social action does nothing (e.g. HELLO while engaged).
4. The robot acts. Moves 0-23: walls and the human's cell stop it (last free cell);
   its orientation becomes the move direction even if blocked. STAY and the social
   actions leave it in place. LOOK_H turns it to the angle (the robot knows where
   the human is, even behind a wall). GO_TO_HUMAN (only if the human is not engaged
   after step 2, else nothing): the robot is placed where a speed-2 move from the
   human's cell along the human's orientation ends (walls stop it; two cells ahead of
   the gaze in the open), with a random orientation (the option does not choose
   one); if that cell is the human's own (human facing a wall) nothing happens.
5. The human reacts. Engaged: its gaze tracks the robot (orientation = quantised
   direction human -> robot, at the robot's new cell); at level 7 it walks toward
   the robot *as it saw it at the start of the step* — along the direction opposite
   to the observed angle — at a speed drawn from s_H, unless the robot did HELLO,
   COME or POINTING this step; it stops at walls and before the robot's (new) cell,
   then looks at the robot again. (The human walks with a one-step lag, as in the
   reference implementation; this also makes the direction it walks a function of
   the observed state, so the reward is Markov in the social observation. The gaze
   is *not* the reference's: it aims at the robot's cell before the robot's move and
   is never re-aimed — paper rule 4 below.)
   Not engaged:
   with probability r_H it walks in a uniformly random direction at a speed drawn
   from s_H and faces that direction; then, with probability O_H, it turns to one
   of the 7 *other* orientations uniformly (so O_H is exactly the rate of random
   turns). The two agents never share a cell.
6. Reward +1 if the level is 7 and the human moved (changed cell) in the required
   direction of the observed state.
7. With probability ``redraw_p`` (paper: 0.2) a new required direction is drawn
   uniformly from the 8 (it may repeat).

Paper rules (fields of :class:`~simlab.visitlab.perception.Perception`, read from
``pcfg``; the thesis variant has them off):

* ``gaze_before_move`` (rule 4): in 5, an engaged human's orientation becomes the
  direction to the robot's cell *before* the robot's move (the cell it walks
  toward) and it is not re-aimed after walking.
* ``gth_before_attention`` (rule 5): in 4, GO_TO_HUMAN works if the human was not
  engaged at the start of the step (before 2); the robot lands where the speed-2
  move along the gaze ends, even on the human's cell.
* ``share_cells`` (rule 6): moves of either agent ignore the other (they may share
  a cell; a following human may pass the robot), random placements may coincide,
  and a random turn draws among all 8 orientations.

Go-to-human step (:func:`gth_step`): the robot moves as in 4; the human (if it
has parameters) behaves as a human who is not engaged (5); reward +1 if, after
the step, the human looks at the robot (facing field and line of sight) at a
distance class 1-3.

Navigation step (:func:`nav_step`): the robot moves (no human); reward +1 if the
new cell lies in the goal room.

Note for developers: the kernels are compiled with ``cache=True`` and numba does
not track dependencies between files; the fused loops of :mod:`simlab.visitlab.fused`
still see an edit here because simlab keeps one numba cache directory per version of its
source (:mod:`simlab.base._numba_cache`; with ``NUMBA_CACHE_DIR`` set by hand, or numba
imported before simlab, delete the cache files yourself).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from simlab.visitlab.actions import ACTION_DIR
from simlab.visitlab.grid import move, move_action_cell
from simlab.visitlab.humans import H_FAIL, H_LOSE, H_MOVE, H_POINT, H_S1, H_S2, H_TURN
from simlab.visitlab.perception import (
    P_GAZE_BEFORE,
    P_GTH_BEFORE,
    P_SHARE,
    direction_between,
    percepts,
)

# Layout of the world-state array ``st``.
S_ROBOT, S_ROBOT_ORI, S_HUMAN, S_HUMAN_ORI, S_ENGAGED, S_REQ_DIR, S_GOAL, S_HUMAN_MOVE = range(8)
N_STATE = 8

#: Social observation: ravel_multi_index((interaction, distance, direction, angle), SOCIAL_DIMS)
SOCIAL_DIMS = (8, 5, 8, 8)
N_SOCIAL_STATES = 2560
#: Go-to-human observation: ravel_multi_index((human_orientation, distance, angle), GTH_DIMS)
GTH_DIMS = (8, 5, 8)
N_GTH_STATES = 320

#: Go-to-human episode variants (thesis Fig. 4.4).
GTH_RANDOM, GTH_FIXED_POSITIONS, GTH_FIXED = 0, 1, 2
GTH_VARIANTS = ("random", "fixed_positions", "fixed")

_HELLO, _COME, _POINTING, _LOOK_H, _GO_TO_HUMAN = 26, 27, 28, 25, 29


def new_state() -> np.ndarray:
    """A zeroed world-state array (int64, shape ``(N_STATE,)``)."""
    st = np.zeros(N_STATE, dtype=np.int64)
    st[S_HUMAN_MOVE] = -1
    return st


# --------------------------------------------------------------------------- human


@njit(cache=True)
def draw_speed(rng: np.random.Generator, hp: np.ndarray) -> int:
    """Human speed 1-3 drawn from s_H (one uniform draw)."""
    u = rng.random()
    if u < hp[H_S1]:
        return 1
    if u < hp[H_S1] + hp[H_S2]:
        return 2
    return 3


@njit(cache=True)
def human_idle(
    walls_h: np.ndarray, walls_v: np.ndarray, st: np.ndarray, hp: np.ndarray,
    rng: np.random.Generator, share: bool = False,
) -> int:
    """Behaviour of a human who is not engaged; returns the direction moved or -1.

    Draws, in order: u < r_H (then a direction and a speed), u < O_H (then a new
    orientation among the 7 others; among all 8 with ``share``, paper rule 6).
    """
    moved = -1
    if rng.random() < hp[H_MOVE]:
        d = rng.integers(0, 8)
        speed = draw_speed(rng, hp)
        new = move(walls_h, walls_v, st[S_HUMAN], d, speed, -1 if share else st[S_ROBOT])
        st[S_HUMAN_ORI] = d
        if new != st[S_HUMAN]:
            moved = d
            st[S_HUMAN] = new
    if rng.random() < hp[H_TURN]:
        if share:
            st[S_HUMAN_ORI] = rng.integers(0, 8)
        else:
            k = rng.integers(0, 7)
            st[S_HUMAN_ORI] = k if k < st[S_HUMAN_ORI] else k + 1
    return moved


# --------------------------------------------------------------------------- social


@njit(cache=True)
def social_obs(
    walls_h: np.ndarray, walls_v: np.ndarray, los: np.ndarray, pcfg: np.ndarray, st: np.ndarray
) -> int:
    """Observation index 0-2559 of the social module for the world state ``st``."""
    level, dist, angle, _, _, _ = percepts(walls_h, walls_v, los, pcfg, st[S_ROBOT],
                                           st[S_ROBOT_ORI], st[S_HUMAN], st[S_HUMAN_ORI])
    if st[S_ENGAGED] >= 5:
        level = st[S_ENGAGED]
    return ((level * 5 + dist) * 8 + st[S_REQ_DIR]) * 8 + angle


@njit(cache=True)
def interaction_level(
    walls_h: np.ndarray, walls_v: np.ndarray, los: np.ndarray, pcfg: np.ndarray, st: np.ndarray
) -> int:
    """Interaction level 0-7 of the world state (engagement, else the percept level)."""
    if st[S_ENGAGED] >= 5:
        return st[S_ENGAGED]
    level, _, _, _, _, _ = percepts(walls_h, walls_v, los, pcfg, st[S_ROBOT], st[S_ROBOT_ORI],
                                    st[S_HUMAN], st[S_HUMAN_ORI])
    return level


@njit(cache=True)
def place_two_agents(
    st: np.ndarray, rng: np.random.Generator, n_cells: int, robot_cell: int, human_cell: int,
    share: bool = False,
) -> None:
    """Put human and robot on distinct cells (any cells with ``share``); ``-1`` means
    uniformly random."""
    st[S_HUMAN] = human_cell if human_cell >= 0 else rng.integers(0, n_cells)
    if share:
        st[S_ROBOT] = robot_cell if robot_cell >= 0 else rng.integers(0, n_cells)
    elif robot_cell >= 0 and robot_cell != st[S_HUMAN]:
        st[S_ROBOT] = robot_cell
    else:
        r = rng.integers(0, n_cells - 1)
        st[S_ROBOT] = r if r < st[S_HUMAN] else r + 1


@njit(cache=True)
def social_reset(
    st: np.ndarray, rng: np.random.Generator, n_cells: int, robot_cell: int, human_cell: int,
    share: bool = False,
) -> None:
    """New social episode: positions (``-1`` = random; may coincide with ``share``),
    random orientations and required direction, human not engaged."""
    place_two_agents(st, rng, n_cells, robot_cell, human_cell, share)
    st[S_ROBOT_ORI] = rng.integers(0, 8)
    st[S_HUMAN_ORI] = rng.integers(0, 8)
    st[S_REQ_DIR] = rng.integers(0, 8)
    st[S_ENGAGED] = 0
    st[S_GOAL] = 0
    st[S_HUMAN_MOVE] = -1


@njit(cache=True, inline="always")
def _social_action(action: int, e: int, level: int, appropriate: bool, hp: np.ndarray,
                   rng: np.random.Generator) -> int:
    """Step 3 of a social step (module docstring): the engagement ``e`` after the social
    action ``action`` (hello, come, pointing) at perceived ``level``."""
    if action == _HELLO:
        if (level == 3 or level == 4) and appropriate:
            u = rng.random()
            if level == 4 or u >= hp[H_FAIL]:
                e = 5
    elif action == _COME:
        if e == 5:
            e = 7 if rng.random() >= hp[H_POINT] else 6
    elif action == _POINTING:
        if e == 6:
            e = 7
    return e


@njit(cache=True, inline="always")
def _engaged_human(walls_h: np.ndarray, walls_v: np.ndarray, pcfg: np.ndarray, hp: np.ndarray,
                   st: np.ndarray, e: int, action: int, follow_dir: int,
                   rng: np.random.Generator) -> int:
    """Step 5 of a social step for an engaged human (``e`` >= 5): it turns to the robot
    and, following (``e`` == 7) after a non-social action, walks ``follow_dir``; updates
    ``st``, returns the direction it moved (-1: none)."""
    width = walls_h.shape[1]
    share = pcfg[P_SHARE] != 0
    moved = -1
    gaze_before = pcfg[P_GAZE_BEFORE] != 0
    if gaze_before:
        st[S_HUMAN_ORI] = follow_dir
    elif st[S_HUMAN] != st[S_ROBOT]:
        st[S_HUMAN_ORI] = direction_between(width, st[S_HUMAN], st[S_ROBOT])
    if e == 7 and not (_HELLO <= action <= _POINTING):
        d = follow_dir
        speed = draw_speed(rng, hp)
        new = move(walls_h, walls_v, st[S_HUMAN], d, speed, -1 if share else st[S_ROBOT])
        if new != st[S_HUMAN]:
            moved = d
            st[S_HUMAN] = new
            if not gaze_before and new != st[S_ROBOT]:
                st[S_HUMAN_ORI] = direction_between(width, st[S_HUMAN], st[S_ROBOT])
    return moved


@njit(cache=True)
def social_step(
    walls_h: np.ndarray,
    walls_v: np.ndarray,
    los: np.ndarray,
    pcfg: np.ndarray,
    hp: np.ndarray,
    redraw_p: float,
    st: np.ndarray,
    action: int,
    rng: np.random.Generator,
) -> float:
    """One social step (module docstring, steps 1-7); updates ``st``, returns the reward."""
    width = walls_h.shape[1]
    level_p, dist, angle, _, _, _ = percepts(walls_h, walls_v, los, pcfg, st[S_ROBOT],
                                             st[S_ROBOT_ORI], st[S_HUMAN], st[S_HUMAN_ORI])
    appropriate = 1 <= dist <= 3
    share = pcfg[P_SHARE] != 0
    e = st[S_ENGAGED]
    engaged_before = e >= 5
    # 2. attention
    if e >= 5:
        lost = rng.random() < hp[H_LOSE]
        if lost or not appropriate:
            e = 0
    level = e if e >= 5 else level_p
    # 3. social actions
    e = _social_action(action, e, level, appropriate, hp, rng)
    # the human walks toward where it saw the robot at the start of the step
    follow_dir = direction_between(width, st[S_HUMAN], st[S_ROBOT])
    # 4. the robot acts
    if action < 24:
        st[S_ROBOT] = move_action_cell(walls_h, walls_v, st[S_ROBOT], action,
                                       -1 if share else st[S_HUMAN])
        st[S_ROBOT_ORI] = ACTION_DIR[action]
    elif action == _LOOK_H:
        st[S_ROBOT_ORI] = angle
    elif action == _GO_TO_HUMAN:
        _go_to_human(walls_h, walls_v, pcfg, st, engaged_before, e, rng)
    # 5. the human reacts
    if e >= 5:
        moved = _engaged_human(walls_h, walls_v, pcfg, hp, st, e, action, follow_dir, rng)
    else:
        moved = human_idle(walls_h, walls_v, st, hp, rng, share)
    st[S_ENGAGED] = e
    st[S_HUMAN_MOVE] = moved
    # 6. reward
    reward = 1.0 if (e == 7 and moved == st[S_REQ_DIR]) else 0.0
    # 7. required direction
    if rng.random() < redraw_p:
        st[S_REQ_DIR] = rng.integers(0, 8)
    return reward


@njit(cache=True)
def _go_to_human(walls_h, walls_v, pcfg, st, engaged_before, e, rng):
    """GO_TO_HUMAN in the social module (step 4; paper rule 5 with ``P_GTH_BEFORE``)."""
    paper = pcfg[P_GTH_BEFORE] != 0
    if (engaged_before if paper else e >= 5):
        return
    target = move(walls_h, walls_v, st[S_HUMAN], st[S_HUMAN_ORI], 2, -1)
    if paper or target != st[S_HUMAN]:
        st[S_ROBOT] = target
        st[S_ROBOT_ORI] = rng.integers(0, 8)


# --------------------------------------------------------------------------- go to human


@njit(cache=True)
def gth_obs(
    walls_h: np.ndarray, walls_v: np.ndarray, los: np.ndarray, pcfg: np.ndarray, st: np.ndarray
) -> int:
    """Observation index 0-319 of the go-to-human module."""
    _, dist, angle, _, _, _ = percepts(walls_h, walls_v, los, pcfg, st[S_ROBOT], st[S_ROBOT_ORI],
                                       st[S_HUMAN], st[S_HUMAN_ORI])
    return (st[S_HUMAN_ORI] * 5 + dist) * 8 + angle


@njit(cache=True)
def gth_reset(
    st: np.ndarray,
    rng: np.random.Generator,
    n_cells: int,
    variant: int,
    robot_cell: int,
    human_cell: int,
    robot_ori: int,
    human_ori: int,
    share: bool = False,
) -> None:
    """New go-to-human episode for a variant (0 random, 1 fixed positions, 2 all fixed).

    Random positions are uniform over distinct cells; random orientations uniform.
    """
    if variant == GTH_RANDOM:
        place_two_agents(st, rng, n_cells, -1, -1, share)
    else:
        st[S_HUMAN] = human_cell
        st[S_ROBOT] = robot_cell
    if variant == GTH_FIXED:
        st[S_ROBOT_ORI] = robot_ori
        st[S_HUMAN_ORI] = human_ori
    else:
        st[S_ROBOT_ORI] = rng.integers(0, 8)
        st[S_HUMAN_ORI] = rng.integers(0, 8)
    st[S_ENGAGED] = 0
    st[S_REQ_DIR] = 0
    st[S_GOAL] = 0
    st[S_HUMAN_MOVE] = -1


@njit(cache=True)
def gth_step(
    walls_h: np.ndarray,
    walls_v: np.ndarray,
    los: np.ndarray,
    pcfg: np.ndarray,
    hp: np.ndarray,
    human_moves: bool,
    st: np.ndarray,
    action: int,
    rng: np.random.Generator,
) -> float:
    """One go-to-human step (actions 0-24); returns the reward."""
    share = pcfg[P_SHARE] != 0
    if action < 24:
        st[S_ROBOT] = move_action_cell(walls_h, walls_v, st[S_ROBOT], action,
                                       -1 if share else st[S_HUMAN])
        st[S_ROBOT_ORI] = ACTION_DIR[action]
    if human_moves:
        st[S_HUMAN_MOVE] = human_idle(walls_h, walls_v, st, hp, rng, share)
    _, dist, _, _, h_looks, _ = percepts(walls_h, walls_v, los, pcfg, st[S_ROBOT],
                                         st[S_ROBOT_ORI], st[S_HUMAN], st[S_HUMAN_ORI])
    return 1.0 if (h_looks and 1 <= dist <= 3) else 0.0


# --------------------------------------------------------------------------- navigation


@njit(cache=True)
def nav_reset(
    st: np.ndarray,
    rng: np.random.Generator,
    n_cells: int,
    start_cell: int,
    goal_label: int,
    goal_labels: np.ndarray,
) -> None:
    """New navigation episode; ``-1`` start: uniform cell; ``-1`` goal: uniform among
    ``goal_labels``."""
    st[S_ROBOT] = start_cell if start_cell >= 0 else rng.integers(0, n_cells)
    if goal_label >= 0:
        st[S_GOAL] = goal_label
    else:
        st[S_GOAL] = goal_labels[rng.integers(0, goal_labels.shape[0])]
    st[S_ROBOT_ORI] = 0
    st[S_HUMAN] = -1
    st[S_HUMAN_MOVE] = -1


@njit(cache=True)
def nav_obs(st: np.ndarray, n_cells: int) -> int:
    """Navigation observation: cell + goal_label * n_cells."""
    return st[S_ROBOT] + st[S_GOAL] * n_cells


@njit(cache=True)
def nav_step(
    walls_h: np.ndarray, walls_v: np.ndarray, labels: np.ndarray, st: np.ndarray, action: int
) -> float:
    """One navigation step (actions 0-24); reward 1 inside the goal room."""
    if action < 24:
        st[S_ROBOT] = move_action_cell(walls_h, walls_v, st[S_ROBOT], action, -1)
        st[S_ROBOT_ORI] = ACTION_DIR[action]
    return 1.0 if labels[st[S_ROBOT]] == st[S_GOAL] else 0.0
