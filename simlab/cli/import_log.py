"""``simlab import-log``: a real robot's pose log (no action column) -> a simlab dataset.

The options are the fields of :class:`simlab.data.poselog.ImportLogConfig`.
"""

from __future__ import annotations

import argparse

HELP = "segment a pose log 't x y yaw [cell [n_cells]]' into decisions and write a dataset"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.data.poselog import ImportLogConfig

    ImportLogConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from simlab.data.poselog import ImportLogConfig, import_log

    cfg = ImportLogConfig.from_args(args)
    res = import_log(cfg)
    per_action = np.bincount(res.actions, minlength=res.action_set.n_actions)
    print(f"{res.samples} samples -> {res.decisions} decisions ({res.blocked} blocked), "
          f"{res.action_set.describe()}, states from the {res.state_source}")
    print("decisions per action: " + " ".join(str(int(n)) for n in per_action))
    if res.before_state:
        print(f"{res.before_state} decision(s) left out: they start or end before their "
              "state existed (cell >= n_cells)")
    if res.cell_check is not None:
        print("\n".join(res.cell_check.lines()))
    if cfg.map is not None:
        print(f"{res.off_map} pose samples off the map's free pixels")
    print(f"wrote {res.out}")
    return 0
