"""Sim-to-real calibration of the primitive parameters: the physics twin
made to move like the real robot whose transitions thesis 3.2.5 counted.

* :mod:`simlab.calibration.metrics` — distances and summaries of transition tables
  (visit-weighted total variation, its bootstrap sampling floor, argmax agreement, ...);
* :mod:`simlab.calibration.signature` — what the real table says before any simulation
  (self-transition share, cell size against move length) and the start and warnings it
  gives;
* :mod:`simlab.calibration.space` — the searched parameters as data (name, bounds, scale,
  or choices);
* :mod:`simlab.calibration.config` — what a calibration is given: the real table and the
  options;
* :mod:`simlab.calibration.walks` — a candidate's walk (``collect``) as a count table in the
  real action set, on the parallel layer;
* :mod:`simlab.calibration.budget` — how many transitions each stage walks, sized from the
  matched floor;
* :mod:`simlab.calibration.objective` — what the search minimises: a distance and the
  robot's signature at its own visits;
* :mod:`simlab.calibration.search` — the seeded multi-fidelity search over the space
  (Optuna's samplers, successive halving);
* :mod:`simlab.calibration.stages` — :func:`~simlab.calibration.stages.calibrate`: search,
  confirm the best on fresh seeds, walk the twins and score their transfer;
* :mod:`simlab.calibration.transfer` — twin policies scored on the real model
  (``simlab transfer``): shortest-path solvers, models, the score, its report and command;
* :mod:`simlab.calibration.report` — the calibrated ``[primitives]`` TOML, JSON/markdown
  reports and the figure;
* :mod:`simlab.calibration.command` — ``simlab calibrate`` as a function of files
  (:func:`~simlab.calibration.command.calibrate_files`);
* :mod:`simlab.calibration.pool` — several calibrations of one lab read together
  (``simlab calibrate-pool``): their winners on common fresh walks, the basins within
  sampling of the best, what the data allow across them, an ensemble across basins.
"""
