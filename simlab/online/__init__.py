"""Online learning while driving, and MB/MF meta-control (Dromnelle et al. 2022).

* :mod:`simlab.online.meta` — the meta-controller: MF/MB experts, criteria, costs (numba);
* :mod:`simlab.online.task` — an online task on an empirical MDP with its change schedule
  (goal change, passages closing);
* :mod:`simlab.online.loop` — the fused online loop on an empirical MDP;
* :mod:`simlab.online.physics` — the same agents learning in physics, decision by decision;
* :mod:`simlab.online.command` — ``simlab online``;
* :mod:`simlab.online.experiments` — the runners of ``experiments/online_*.toml``.
"""
