"""The options of ``simlab visitlab train`` and ``simlab visitlab show``: the environment
group both share (:class:`VisitlabEnvOptions`), each command's configuration (the CLI is
generated from it), and the spelling of command-line values and agent overrides.

Options that do not apply to the chosen task are refused here, so a run never starts
with an option it would ignore.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, option
from simlab.visitlab import TASKS
from simlab.visitlab.fused import loop_agent_config
from simlab.visitlab.humans import human as preset_human

__all__ = ["ShowConfig", "VisitlabEnvOptions", "VisitlabTrainConfig", "parse_overrides",
           "parse_value"]


def parse_value(text: str) -> Any:
    """The value a command-line word spells (``--set``, ``--start``, ``--goal``): ``none``
    / ``null`` -> None, ``true`` / ``false``, a whole or decimal number, else the text."""
    low = text.strip().lower()
    if low in ("none", "null"):
        return None
    if low in ("true", "false"):
        return low == "true"
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def parse_overrides(items: Any) -> dict[str, Any]:
    """Agent overrides from ``KEY=VALUE`` words (``--set``, or a TOML list of them; values
    by :func:`parse_value`) or a table ``{key: value}`` (taken as is)."""
    if isinstance(items, dict):
        return dict(items)
    if not isinstance(items, list | tuple):
        raise ConfigError(f"expected a table or a list of KEY=VALUE, got {items!r}", key="--set")
    out: dict[str, Any] = {}
    for item in items:
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(f"expected KEY=VALUE, got {item!r}", key="--set")
        key, value = item.split("=", 1)
        out[key.strip()] = parse_value(value)
    return out


@dataclass(frozen=True, kw_only=True)
class VisitlabEnvOptions(CommandConfig):
    """The environment options of ``visitlab train`` and ``visitlab show`` (a field group:
    inherit it). :meth:`env_kwargs` turns them into the keyword arguments of
    :func:`~simlab.visitlab.training.make_env` /
    :func:`~simlab.visitlab.training.train`; options that do not apply to ``task`` are refused
    here, so a run never starts with an option it would ignore."""

    task: str = option("social", "module to run", choices=TASKS)
    variant: str = option("thesis", "thesis or paper settings", choices=("thesis", "paper"))
    human: str | None = option(
        None, "human preset(s), comma-separated: easy, medium, hard, H1, H2, H3 (social "
        "default: easy / H1; go-to-human default: a still human)")
    layout: str | None = option(
        None, "gridworld, gridworld-HxW, paper or lab (default: the task's)")
    layout_seed: int | None = option(None, "seed of a random lab layout")
    episode: str | None = option(
        None, "go-to-human episode variant (thesis Fig. 4.4; default random)",
        choices=("random", "fixed_positions", "fixed"))
    start: int | str | None = option(
        None, "navigation start: 'random' or a cell index (default: the variant's)", parse=str)
    goal: int | str | None = option(
        None, "navigation goal room: 'random' or a label (default: the variant's)", parse=str)
    steps: int | None = option(
        None, "steps per trial (default: thesis 50 nav / 40 others, paper 20)")
    seed: int = option(0, "root seed")

    def validate(self) -> None:
        validation.whole(self.seed, "seed")
        if self.steps is not None:
            validation.whole(self.steps, "steps", minimum=1)
        if self.episode is not None and self.task != "gotohuman":
            raise ConfigError("only the gotohuman task has episode variants", key="--episode")
        for key in ("start", "goal"):
            value = getattr(self, key)
            if value is not None and self.task != "nav":
                raise ConfigError("only the nav task has a start and a goal", key=f"--{key}")
            if isinstance(value, bool) or not isinstance(value, int | str | None):
                raise ConfigError(f"expected 'random', a number or a label, got {value!r}",
                                  key=key)
        if self.human is not None:
            if self.task == "nav":
                raise ConfigError("the navigation task has no human", key="--human")
            for name in self.humans():
                preset_human(name)  # an unknown preset is named before any run

    def humans(self) -> list[str | None]:
        """The human presets of ``human`` (``[None]``: the task's default)."""
        if self.human is None:
            return [None]
        return [h.strip() for h in self.human.split(",") if h.strip()]

    def env_kwargs(self, human: str | None = None) -> dict[str, Any]:
        """Keyword arguments of the env: the options given (``steps`` as ``max_steps``;
        ``start`` / ``goal`` words by :func:`parse_value`), and ``human`` when not None."""
        kw: dict[str, Any] = {}
        for key in ("layout", "layout_seed", "episode"):
            if getattr(self, key) is not None:
                kw[key] = getattr(self, key)
        for key in ("start", "goal"):
            value = getattr(self, key)
            if value is not None:
                kw[key] = parse_value(value) if isinstance(value, str) else value
        if self.steps is not None:
            kw["max_steps"] = self.steps
        if human is not None:
            kw["human"] = human
        return kw


@dataclass(frozen=True, kw_only=True)
class ShowConfig(VisitlabEnvOptions):
    """Options of ``simlab visitlab show``: one episode of
    :func:`~simlab.visitlab.training.make_env`'s env with a
    random policy, or greedy on a Q table of a ``visitlab train`` curves file."""

    COMMAND = "visitlab show"

    q: Path | None = option(None, "curves.npz from 'visitlab train': act greedily with its Q")
    run: int = option(0, "run index in the curves file")
    seed_index: int = option(0, "seeded run whose Q to use")
    png: Any | None = option(None, "also save the last frame as a PNG")
    overwrite: bool = option(False, "replace an existing --png")

    def validate(self) -> None:
        super().validate()
        validation.spelled_path(self.png, "png")


@dataclass(frozen=True, kw_only=True)
class VisitlabTrainConfig(VisitlabEnvOptions):
    """Options of ``simlab visitlab train`` /
    :func:`~simlab.visitlab.training.train_command`: every agent of ``agent`` with every
    human of ``human`` (comma-separated), trained by :func:`~simlab.visitlab.training.train`
    and saved together into ``out``. ``agent_overrides`` is ``--set KEY=VALUE``
    (repeatable, so the CLI module adds it): a TOML ``set`` / ``agent_overrides`` table,
    or a list of ``KEY=VALUE``."""

    COMMAND = "visitlab train"
    ARGUMENTS = ("task", "agent")

    agent: str = option(
        "mb-egreedy", "agent name(s), comma-separated: q-learning, q-softmax, mb-egreedy, "
        "vi-softmax, rmax, sliding-window, passive-observer")
    trials: int | None = option(
        None, "trials per seed (default: nav 2000, social 40000, gotohuman 2000)")
    seeds: int = option(10, "independent runs")
    agent_overrides: Any | None = option(
        None, "agent parameter overrides {key: value} (--set on the command line)",
        flag="set", cli=False)
    workers: int = option(1, "processes for the seeds")
    out: Path = option(help="output directory")
    title: str = option("", "plot title")
    overwrite: bool = option(False, "replace existing output files")
    progress: bool = option(True, "progress bar (--no-progress hides it)")

    def validate(self) -> None:
        super().validate()
        if self.trials is not None:
            validation.whole(self.trials, "trials", minimum=1)
        validation.whole(self.seeds, "seeds", minimum=1)
        validation.whole(self.workers, "workers", minimum=1)
        if self.agent_overrides is not None:
            object.__setattr__(self, "agent_overrides", parse_overrides(self.agent_overrides))
        if not self.agents():
            raise ConfigError("no agent named", key="agent")
        for name in self.agents():  # unknown agents and overrides named before any run
            loop_agent_config(name, self.task, self.variant, self.agent_overrides)

    def agents(self) -> list[str]:
        """The agent names of ``agent``."""
        return [a.strip() for a in self.agent.split(",") if a.strip()]
