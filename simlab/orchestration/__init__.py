"""Orchestration: the physics chain's stages, their cache, the pipeline and its report.

``stages`` (cached stage runner), ``mapping`` (the mapping drive and occupancy map),
``pipeline`` (map -> states -> dataset -> MDP -> training -> replay), ``report``
(``report.md`` and the pipeline's figures), ``warmup`` (numba compile warm-up beside
the physics). These compose the lower layers (physics, data, training, replay); nothing
below imports them.
"""
