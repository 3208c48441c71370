"""Every ``simlab`` subcommand as a Python function.

``simlab.commands.drive(arena="table", steps=100, seed=0)`` does what
``simlab drive --arena table --steps 100 --seed 0`` does and returns its result
object instead of printing. Functions are imported lazily from the modules that
own them, so this module is cheap to import.
"""

from __future__ import annotations

from simlab.base.lazy import lazy_exports

#: Function name -> "module:attribute".
_FUNCTIONS: dict[str, str] = {
    "drive": "simlab.physics.drive:drive",
    "map": "simlab.orchestration.mapping:build_map",
    "arena_from_map": "simlab.physics.map_arena:arena_from_map",
    "discretize": "discretize.command:discretize_command",
    "collect": "simlab.data.collect:collect",
    "import_log": "simlab.data.poselog:import_log",
    "estimate": "simlab.data.estimate:estimate",
    "export_minari": "simlab.envs.minari_export:export_minari",
    "export_bag": "simlab.ros.export:export_bag",
    "import_bag": "simlab.ros.importer:import_bag",
    "train": "simlab.training.train:train",
    "replay": "simlab.replay.replay:replay",
    "calibrate": "simlab.calibration.command:calibrate_command",
    "calibrate_pool": "simlab.calibration.pool:pool_command",
    "transfer": "simlab.calibration.transfer:transfer_command",
    "pipeline": "simlab.orchestration.pipeline:pipeline",
    "social_pipeline": "simlab.social.pipeline:social_pipeline",
    "visitlab_train": "simlab.visitlab.training:train_command",
    "reproduce": "simlab.experiments.reproduce:reproduce",
    "online": "simlab.online.command:online",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _FUNCTIONS)
