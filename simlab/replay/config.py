"""The options of ``simlab replay``, spelled once (:class:`ReplayConfig`).

The command line (``simlab replay --help``), a TOML file (``--config FILE``) and the
Python function :func:`simlab.replay.replay.replay` (``replay(cfg)`` or the same fields as
keyword arguments) are generated from this one dataclass.

Decisions: ``arena``, ``states`` and ``qtables`` keep accepting in-memory objects from
Python (an ``ArenaConfig``, a discretizer, a mapping ``goal -> Q``), so they are typed
``Any`` and checked where they are loaded (the loaders name the file). The objects
``params``, ``mcl_params`` and ``action_set`` are Python-only (``cli=False``); the CLI
builds ``params`` from the primitive flags it shares with ``simlab collect``.
``states`` and ``out`` keep their library defaults (None, ``runs/replay``); the CLI asks
for both explicitly, as before.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from simlab.base import validation as v
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, option
from simlab.localization.sources import POSE_SOURCES
from simlab.physics.rate import rate_option, resolve_rate

POLICIES = ("greedy", "random")


@dataclass(frozen=True, kw_only=True)
class ReplayConfig(CommandConfig):
    """Every option of a closed-loop replay (see :mod:`simlab.replay.replay`); ``physics_hz``
    None steps at the rate of the MDP's dataset (else the default rate)."""

    COMMAND = "replay"

    arena: Any = option("table", "built-in arena name, .toml path (or, from Python, an "
                                 "ArenaConfig)")
    states: Any | None = option(None, "states file written by `simlab discretize` (JSON; "
                                      "required on the command line; from Python also a "
                                      "discretizer)", metavar="JSON")
    qtables: Any | None = option(None, "output directory of `simlab train` (q_<goal>.npz per "
                                       "goal; from Python also a mapping goal -> Q (S, A))",
                                 metavar="DIR")
    hours: float = option(3.0, "robot time to replay, driving + idle latency (h)")
    pose_source: str = option("truth", "pose the robot decides from", choices=POSE_SOURCES)
    seed: int = option(0, "root seed")
    out: Any = option("runs/replay", "output directory (required on the command line)",
                      metavar="DIR")
    policy: str = option("greedy", "greedy: the Q-tables; random: uniform actions",
                         choices=POLICIES)
    map: Any | None = option(None, "map_server map.yaml to localize on and draw (default: "
                                   "the arena's own geometry rasterised at 1 cm)",
                             metavar="YAML")
    return_to_start: bool = option(False, "drive back to the start pose after each goal "
                                          "(thesis go_back_initial_pose)")
    video: bool = option(False, "also write replay.gif (and replay.mp4 with imageio-ffmpeg)")
    progress: bool = option(True, "show progress bars (robot hours)")
    overwrite: bool = option(False, "replace existing outputs")
    mdp: Any | None = option(None, "mdp.npz for the predicted rate (default: the one the "
                                   "Q-tables were trained on)", metavar="NPZ")
    baseline_hours: float | None = option(None, "random-policy baseline replay length (h; "
                                                "default: --hours; 0: none)", metavar="H")
    retry_blocked: bool = option(True, "after a blocked primitive, exclude the refused action "
                                       "at that pose")
    escape_radius: float = option(0.03, "loop watchdog (m): random action instead of "
                                        "repeating an action from within this distance of an "
                                        "earlier decision of the same goal episode; 0: off",
                                  metavar="M")
    epsilon: float = option(0.0, "probability of a uniformly random action per decision")
    params: Any | None = option(None, "PrimitiveParams (default: those of the MDP's "
                                      "dataset)", cli=False)
    primitives: Any | None = option(None, "the [primitives] TOML file params were read from "
                                    "(recorded in replay.json; from Python without params, "
                                    "params are read from it)", cli=False)
    mcl_params: Any | None = option(None, "MCLParams of the mcl pose source (default values)",
                                    cli=False)
    max_frames: int = option(150, "at most this many video frames")
    action_set: Any | None = option(None, "ActionSet of in-memory Q-tables", cli=False)
    goals: Any | None = option(None, "goals to switch between: arena goal names or state-id "
                                     "goals as train --goal-states names them (s18, s18+19), "
                                     "comma-separated; default: all of the arena's",
                               metavar="NAMES")
    parallel: bool = option(True, "run the random baseline in a process of its own on 2 or "
                                  "more cores, and the mcl filter too on 3 or more; "
                                  "bit-identical results")
    pool: Any | None = option(None, "a one-process executor to run the random baseline (and "
                                    "encode the video) in, instead of a fresh process: a "
                                    "warmed worker lent by the caller, left open", cli=False)
    physics_hz: float | None = rate_option()

    def validate(self) -> None:
        v.positive(self.hours, "hours")
        v.whole(self.seed, "seed")
        if self.baseline_hours is not None:
            v.positive(self.baseline_hours, "baseline_hours", allow_zero=True)
        v.number(self.escape_radius, "escape_radius", low=0.0)
        v.probability(self.epsilon, "epsilon")
        v.whole(self.max_frames, "max_frames", minimum=1)
        v.executor(self.pool)
        v.spelled_path(self.primitives, "primitives")
        v.spelled_path(self.map, "map")
        from simlab.physics.arena import check_arena_option

        check_arena_option(self.arena)
        if self.physics_hz is not None:
            resolve_rate(self.physics_hz)
        if self.primitives is not None and self.params is None:
            from simlab.physics.motion import PrimitiveParams

            object.__setattr__(self, "params", PrimitiveParams.from_toml(self.primitives))
        if self.qtables is None and self.policy == "greedy":
            raise ConfigError("a greedy replay needs Q-tables", key="qtables",
                              fix="pass --qtables DIR (the output of `simlab train`) or "
                                  "--policy random")

    @property
    def baseline(self) -> float:
        """Hours of the random baseline actually run (0 for a random-policy replay)."""
        if self.policy == "random":
            return 0.0
        return self.hours if self.baseline_hours is None else float(self.baseline_hours)
