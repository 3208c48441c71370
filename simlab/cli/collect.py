"""``simlab collect``: the epsilon = 1 random-walk transition dataset.

The options are the fields of :class:`simlab.data.collect.CollectConfig`.
"""

from __future__ import annotations

import argparse

HELP = "collect a random-walk transition dataset (Parquet parts + manifest)"


def add_primitive_arguments(parser: argparse.ArgumentParser) -> None:
    """``--primitives FILE.toml`` and the direct flags of
    :class:`~simlab.physics.primitive_options.PrimitiveOptions` (for commands whose own
    options are not a config class yet)."""
    from simlab.physics.primitive_options import PrimitiveOptions

    PrimitiveOptions.add_arguments(parser, config_file=False)


def primitive_params_from_args(args: argparse.Namespace):  # -> PrimitiveParams | None
    """The PrimitiveParams of ``--primitives`` overridden by the direct flags; None when
    none of them is given (the command's default applies)."""
    from simlab.physics.primitive_options import PrimitiveOptions

    return PrimitiveOptions.from_args(argparse.Namespace(
        **{k: v for k, v in vars(args).items() if k != "config"})).primitive_params()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.data.collect import CollectConfig

    CollectConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.data.collect import CollectConfig, collect

    result = collect(CollectConfig.from_args(args))
    rate = result.transitions / result.wall_seconds if result.parts_written else 0.0
    kept = result.parts - result.parts_written
    print(
        f"{result.directory}: {result.transitions} transitions in {result.parts} parts, "
        f"{result.simulated_hours:.2f} simulated h"
        + (f" ({kept} parts were already there)" if kept else "")
        + f"; {result.wall_seconds:.1f} s wall"
        + (f", {rate:.0f} transitions/s" if result.parts_written and not kept else "")
        + ("" if result.complete else " (incomplete)")
        + f"; the walk reached {result.states_visited} of {result.n_states} states"
    )
    from simlab.physics.rate import DEFAULT_HZ

    if result.physics_hz is not None and result.physics_hz != DEFAULT_HZ:
        print(f"physics stepped at {result.physics_hz:g} Hz (the default rate is "
              f"{DEFAULT_HZ:g} Hz; the manifest records it)")
    return 0
