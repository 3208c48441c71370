"""The twin ensemble of a primitives file (``[[ensemble]]``) and the seeded draw of a
member per unit of work (``--ensemble`` of ``collect`` and ``online --arena``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from simlab.base.errors import ConfigError
from simlab.data.collect import CollectConfig
from simlab.physics.motion import PrimitiveParams
from simlab.physics.primitive_options import ensemble_members
from tests.physics.conftest import ensemble_text

MEMBERS = [PrimitiveParams(mode="until_state_change", wall_slide=0.2),
           PrimitiveParams(mode="until_state_change", wall_slide=0.05, fast_speed=0.18),
           PrimitiveParams(turn_rate=0.4)]


def test_the_ensemble_reads_back_member_for_member(tmp_path: Path) -> None:
    path = tmp_path / "p.toml"
    path.write_text(ensemble_text(MEMBERS))
    assert PrimitiveParams.ensemble_from_toml(path) == tuple(MEMBERS)
    assert PrimitiveParams.from_toml(path) == MEMBERS[0]  # [primitives] readers unchanged


@pytest.mark.parametrize(("line", "key", "problem"), [
    ("wall_slide = 1.5", "ensemble[2].wall_slide", "<= 1"),
    ("warp = 9", "ensemble[2].warp", "unknown primitive parameter"),
    ('mode = "teleport"', "ensemble[2].mode", "teleport"),
])
def test_a_bad_member_names_its_index_and_field(tmp_path: Path, line: str, key: str,
                                                problem: str) -> None:
    head, last = ensemble_text(MEMBERS).rsplit("[[ensemble]]", 1)
    name = line.split(" = ")[0]
    rows = [row for row in last.splitlines() if not row.startswith(f"{name} = ")]
    path = tmp_path / "p.toml"  # the last member's field changed
    path.write_text(head + "[[ensemble]]" + "\n".join([*rows, line]) + "\n")
    with pytest.raises(ConfigError) as info:
        PrimitiveParams.ensemble_from_toml(path)
    assert info.value.key == key and info.value.path == str(path)
    assert problem in str(info.value) and str(path) in str(info.value)


def test_a_file_without_an_ensemble_says_where_one_comes_from(tmp_path: Path) -> None:
    path = tmp_path / "p.toml"
    path.write_text(PrimitiveParams().toml_text())
    with pytest.raises(ConfigError, match="several confirmed candidates are within "
                       "sampling of the winner") as info:
        PrimitiveParams.ensemble_from_toml(path)
    assert info.value.key == "ensemble" and "without --ensemble" in info.value.fix
    path.write_text(PrimitiveParams().toml_text() + "[ensemble]\nwall_slide = 0.1\n")
    with pytest.raises(ConfigError, match="array of tables"):
        PrimitiveParams.ensemble_from_toml(path)


def test_a_units_member_depends_on_the_seed_and_its_index_only() -> None:
    draws = ensemble_members(3, 40, 3)
    assert set(draws) == {0, 1, 2}
    assert ensemble_members(3, 7, 3) == draws[:7]  # more units: the first keep theirs
    assert ensemble_members(3, 40, 3) == draws
    assert ensemble_members(4, 40, 3) != draws


def test_the_direct_flags_override_every_member(tmp_path: Path) -> None:
    path = tmp_path / "p.toml"
    path.write_text(ensemble_text(MEMBERS))
    cfg = CollectConfig(states="s.json", out=tmp_path / "o", transitions=10, primitives=path,
                        ensemble=True, decision_latency=1.5)
    members = cfg.primitive_ensemble()
    assert members == tuple(m.replace(decision_latency=1.5) for m in MEMBERS)
    assert CollectConfig(states="s.json", out=tmp_path / "o", transitions=10,
                         primitives=path).primitive_ensemble() is None
