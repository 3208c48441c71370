"""Closed-loop replay of learned Q-tables in physics (thesis 4.5, Fig. 4.10).

:mod:`~simlab.replay.replay` (``simlab replay``: inputs, runs, summary, outputs in order),
:mod:`~simlab.replay.config` (:class:`~simlab.replay.config.ReplayConfig`, every option once),
:mod:`~simlab.replay.loop` (one run: the decision loop, its recorder and log),
:mod:`~simlab.replay.policy` (greedy choice, blocked retries, loop watchdog),
:mod:`~simlab.replay.scheduling` (the baseline and the filter in processes of their own),
:mod:`~simlab.replay.summary` (the typed summary; ``replay.json``),
:mod:`~simlab.replay.writers` (parquet logs, reward plot, video),
:mod:`~simlab.replay.prediction` (the reward rate the empirical MDP predicts, exactly),
:mod:`~simlab.replay.inputs` (Q-tables, model and their checks),
:mod:`~simlab.replay.plots` (cumulative reward, thesis Fig. 4.10),
:mod:`~simlab.replay.video` (top-down GIF, thesis Fig. 4.11).
"""

from __future__ import annotations
