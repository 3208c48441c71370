"""Sim-to-real calibration of the primitive parameters: the physics twin
made to move like the real robot whose transitions thesis 3.2.5 counted.

* :mod:`simlab.calibration.metrics` — distances and summaries of transition tables
  (visit-weighted total variation, its bootstrap sampling floor, argmax agreement, ...);
* :mod:`simlab.calibration.signature` — what the real table says before any simulation
  (self-transition share, cell size against move length) and the start and warnings it
  gives;
* :mod:`simlab.calibration.space` — the searched parameters as data (name, bounds, scale,
  or choices);
* :mod:`simlab.calibration.search` — candidates simulated with ``collect`` and a seeded
  derivative-free search, the best confirmed on fresh seeds;
* :mod:`simlab.calibration.transfer` — twin policies scored on the real model
  (``simlab transfer``);
* :mod:`simlab.calibration.report` — the calibrated ``[primitives]`` TOML, JSON/markdown
  reports and the figure;
* :mod:`simlab.calibration.command` — ``simlab calibrate`` as a function of files
  (:func:`~simlab.calibration.command.calibrate_files`).
"""
