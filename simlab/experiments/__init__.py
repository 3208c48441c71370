"""``simlab reproduce``: one TOML per thesis result, runners, parallel seeds, ``results.md``.

This docstring is **the contract** between the framework and the people who write
experiments. Everything below is enforced by :mod:`simlab.experiments.spec` (the TOML
schema), :mod:`simlab.experiments.registry` (runners), :mod:`simlab.experiments.context`
(what a runner receives and returns) and :mod:`simlab.experiments.reproduce` (the driver).
A complete tiny example: :mod:`simlab.experiments.example` with
``simlab/experiments/example.toml``.

1. One TOML file per result
---------------------------
The experiments of the thesis live in the repository's ``experiments/*.toml``
(``simlab reproduce`` reads every ``*.toml`` there; ``--experiments PATH`` points at
another directory or file). Schema (unknown keys are errors, so typos cannot pass)::

    name = "fig4_8_entropy"        # unique; [a-z0-9_.-]; the output folder DIR/<name>/
    title = "Transition entropy per action"
    reference = "Thesis Fig. 4.8"  # where the result is in the thesis / paper / poster
    claim = "Fast actions have a higher transition entropy than slow ones."
    runner = "physics.entropy"     # a registry key (section 2)

    [params]                       # free-form; handed to the runner as a dict
    arena = "table"

    [budget.quick]                 # tiny: runs in the test suite (seconds)
    seeds = 1                      # required in both budgets: independent runs
    hours = 1.0                    # anything else is free-form (trials, episodes, hours...)

    [budget.full]                  # the thesis's trial counts and 10 seeds
    seeds = 10
    hours = 10.0

    [[expect]]                     # zero or more checks, evaluated on the runner's metrics
    metric = "fast_minus_slow_bits"
    op = ">"
    value = 0.0
    thesis = "fast actions show higher entropy bars than slow ones (Fig. 4.8)"
    budgets = ["full"]             # optional, default ["quick", "full"]

Check operators (``value`` is what the metric is compared with):

=========================  ==================================================
``>=``, ``>``, ``<=``, ``<``  a number
``==``                     a number (exact; use ``approx`` for floats)
``approx``                 a number, with ``tol`` (absolute) and/or ``rel_tol``
``between``                ``[low, high]``, both inclusive
``greater_than_metric``    the name of another metric: ``metric > factor * other``
``less_than_metric``       likewise ``metric < factor * other`` (``factor`` default 1)
=========================  ==================================================

A check whose metric the runner did not return, or returned as ``None``/NaN, **FAILs**
(it is never hidden). A check whose ``budgets`` exclude the current budget is listed as
"not checked at this budget". Every problem in a file raises
:class:`~simlab.base.errors.ConfigError` naming the file and the key (``expect[2].op``).

2. Runners
----------
A runner is a module-level function registered under a key with the decorator
:func:`~simlab.experiments.registry.runner`::

    from simlab.experiments import RunContext, RunResult, runner

    @runner("physics.entropy")
    def entropy(params: dict, budget: dict, ctx: RunContext) -> RunResult: ...

Keys are ``"<group>.<name>"``; :data:`simlab.experiments.registry.RUNNER_MODULES` maps
each group to the module that defines its runners and is imported only when one of them
is needed (so ``simlab reproduce --help`` stays fast). Groups: ``example``
(:mod:`simlab.experiments.example`), ``physics`` (:mod:`simlab.experiments.physics`),
``visitlab`` (``simlab.experiments.visitlab``: the Visit-the-lab results). A module may
import further modules of its own to register more runners.

The runner gets:

* ``params`` — the TOML's ``[params]`` table (a plain dict);
* ``budget`` — the selected ``[budget.<quick|full>]`` table (``budget["seeds"]`` >= 1);
* ``ctx`` — a :class:`~simlab.experiments.context.RunContext`:

  - ``ctx.out`` — the experiment's output folder ``DIR/<name>/`` (created, empty);
    write every figure there;
  - ``ctx.seed`` — the experiment's root :class:`numpy.random.SeedSequence`
    (``SeedSequence(root_seed, spawn_key=(crc32(name),))``: the same numbers whether the
    experiment runs alone (``--only``) or with the others); ``ctx.seeds(n)`` returns its
    first ``n`` children without mutating it (call it as often as you like);
    ``ctx.root_seed`` the integer ``--seed``;
  - ``ctx.map(fn, kwargs_list, desc=...)`` — runs ``fn(**kwargs)`` for every dict of the
    list, in parallel on the chosen backend (local process pool with as many workers as
    cores, or Ray tasks), and returns the results **in the order of the list**. ``fn``
    must be a module-level function and its arguments and result picklable (numbers,
    arrays, dataclasses, SeedSequences, paths); it must not rely on globals set by the
    caller. Deterministic by seed: pass each job its own seed (``ctx.seeds(n)[i]``), so
    both backends give the same numbers. A progress bar counts finished jobs;
  - ``ctx.cache`` — ``DIR/_cache/``, shared by all experiments of the output folder
    (used by the physics runners to collect one dataset for Figs. 4.8-4.10);
  - ``ctx.budget_name`` (``"quick"``/``"full"``), ``ctx.backend_name``,
    ``ctx.progress`` (show bars?), ``ctx.log(message)`` (one line to the console).

The runner returns a :class:`~simlab.experiments.context.RunResult`:

* ``metrics`` — flat ``{name: float | int | bool | None}`` (what checks read; shown in
  the results table);
* ``figures`` — paths of the figures it wrote (under ``ctx.out``), linked in
  ``results.md``;
* ``notes`` — sentences for the reader (e.g. why a shape does not hold);
* ``details`` — optional JSON-ready data (per-action values, curves) saved in
  ``DIR/<name>/result.json``.

A runner raises :class:`~simlab.base.errors.ConfigError` for bad ``params``/``budget``
values (name the key, e.g. ``key="params.hours"``); any exception is caught by the
driver, shown in the table as ERROR, and the other experiments still run.

3. The command
--------------
``simlab reproduce [--only NAME[,NAME]] [--budget quick|full] [--backend local|ray
[--address ADDR]] [--workers N] [--seed S] [--overwrite] --out DIR`` (Python:
:func:`simlab.experiments.reproduce.reproduce`) runs the selected experiments one after
the other (their independent runs in parallel through ``ctx.map``) and writes
``DIR/<name>/`` (figures, ``result.json``, ``error.txt`` if it failed), ``DIR/results.md``
(per result: the thesis's statement, our number, PASS/FAIL for every check, links to the
figures, wall time) and ``DIR/results.json``. Existing experiment folders are not
replaced without ``--overwrite``; results of earlier runs in ``DIR`` of experiments not
selected now are kept in the table (with their budget). The exit code is 1 when an
experiment failed to run (and, with ``--strict``, when a check FAILed).
"""

from __future__ import annotations

from simlab.base.lazy import lazy_exports

_LAZY: dict[str, str] = {
    "RunContext": "simlab.experiments.context",
    "RunResult": "simlab.experiments.context",
    "runner": "simlab.experiments.registry",
    "get_runner": "simlab.experiments.registry",
    "ExperimentSpec": "simlab.experiments.spec",
    "Check": "simlab.experiments.spec",
    "load_experiment": "simlab.experiments.spec",
    "discover_experiments": "simlab.experiments.spec",
    "ReproduceResult": "simlab.experiments.reproduce",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _LAZY)
