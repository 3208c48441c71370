"""Sim-to-real calibration of the primitive parameters: the physics twin
made to move like the real robot whose transitions thesis 3.2.5 counted.

* :mod:`simlab.calibration.metrics` — distances and summaries of transition tables
  (visit-weighted total variation, its bootstrap sampling floor, argmax agreement, ...);
* :mod:`simlab.calibration.space` — the searched parameters as data (name, bounds, scale);
* :mod:`simlab.calibration.search` — candidates simulated with ``collect`` and a seeded
  derivative-free search;
* :mod:`simlab.calibration.report` — the calibrated ``[primitives]`` TOML, JSON/markdown
  reports and the figure;
* :mod:`simlab.calibration.command` — ``simlab calibrate`` as a function of files
  (:func:`~simlab.calibration.command.calibrate_files`).
"""
