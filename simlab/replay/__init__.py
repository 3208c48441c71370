"""Closed-loop replay of learned Q-tables in physics (SPEC A9, thesis 4.5).

:mod:`~simlab.replay.replay` (``simlab replay``: the run, its log and summary),
:mod:`~simlab.replay.prediction` (the reward rate the empirical MDP predicts, exactly),
:mod:`~simlab.replay.inputs` (Q-tables, model and their checks),
:mod:`~simlab.replay.plots` (cumulative reward, thesis Fig. 4.10),
:mod:`~simlab.replay.video` (top-down GIF, thesis Fig. 4.11),
:mod:`~simlab.replay.localization` (the ``mcl`` pose source entry point of the datasets).
"""

from __future__ import annotations
