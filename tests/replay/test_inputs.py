"""The replay's inputs: Q-tables, the model, and how they must agree."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.agents.storage import save_q_table
from simlab.base.errors import ConfigError
from simlab.physics.motion import PrimitiveParams
from simlab.replay.inputs import (
    ModelInputs,
    discover_mdp,
    load_model,
    load_qtables,
    primitive_params_for,
    q_file_name,
)


def test_loads_every_goal_in_arena_order(chain) -> None:
    qt = load_qtables(chain.qtables, chain.goal_names, 41)
    assert qt.Q.shape == (9, 41, 16) and qt.names == chain.goal_names
    np.testing.assert_array_equal(qt.Q[3], chain.Q[chain.goal_names[3]])
    assert discover_mdp(qt) == str(chain.mdp)


def test_missing_goal_names_the_directory_and_the_file(chain, tmp_path) -> None:
    qdir = tmp_path / "q"
    shutil.copytree(chain.qtables, qdir)
    (qdir / q_file_name("SE")).unlink()
    with pytest.raises(ConfigError) as info:
        load_qtables(qdir, chain.goal_names, 41)
    msg = str(info.value)
    assert str(qdir) in msg and "'SE'" in msg and "q_SE.npz" in msg


def test_wrong_shape_names_the_file_and_the_expected_shape(chain, tmp_path) -> None:
    qdir = tmp_path / "q"
    shutil.copytree(chain.qtables, qdir)
    save_q_table(qdir / "q_N.npz", np.zeros((25, 16)), overwrite=True)
    with pytest.raises(ConfigError) as info:
        load_qtables(qdir, chain.goal_names, 41, "states/table.json")
    msg = str(info.value)
    assert "q_N.npz" in msg and "(25, 16)" in msg and "(41, 16)" in msg
    assert "states/table.json" in msg


def test_non_finite_and_missing_tables_in_memory() -> None:
    with pytest.raises(ConfigError, match="no Q-table for goal 'B'"):
        load_qtables({"A": np.zeros((3, 16))}, ("A", "B"), 3)
    with pytest.raises(ConfigError, match="NaN"):
        load_qtables({"A": np.full((3, 16), np.nan)}, ("A",), 3)


def test_model_is_checked_against_states_and_goals(chain) -> None:
    model = load_model(chain.mdp, chain.discretizer, chain.goal_names, chain.goal_masks)
    assert model.T.shape == (41, 16, 41)
    # 3.03 s is the fixture's idle time per transition (conftest); each primitive adds its
    # own driving time on top, so the dataset's seconds per transition exceed it
    assert model.dataset is not None and model.dataset_seconds_per_transition > 3.03
    assert model.primitive_params is None  # a kinematic dataset has no motion primitives
    other = Discretizer(centres=chain.discretizer.centres + 0.01)
    with pytest.raises(ConfigError, match="other states"):
        load_model(chain.mdp, other, chain.goal_names, chain.goal_masks)
    with pytest.raises(ConfigError, match=r"goals \['a', 'b'\] are not among the MDP's"):
        load_model(chain.mdp, chain.discretizer, ("a", "b"), chain.goal_masks[:2])
    # a subset of the MDP's goals, and a state-id goal, are fine
    i = chain.goal_names.index("C")
    sub = load_model(chain.mdp, chain.discretizer, ("C", "s0"),
                     np.stack([chain.goal_masks[i], np.eye(41, dtype=bool)[0]]))
    assert sub.T.shape == (41, 16, 41)
    masks = chain.goal_masks.copy()
    masks[0] = ~masks[0]
    with pytest.raises(ConfigError, match="covers other states"):
        load_model(chain.mdp, chain.discretizer, chain.goal_names, masks)
    small = Discretizer(centres=chain.discretizer.centres[:20])
    with pytest.raises(ConfigError, match=r"\(20, 16, 20\)"):
        load_model(chain.mdp, small, chain.goal_names, chain.goal_masks[:, :20])


def test_primitives_come_from_the_dataset_and_must_match_it(tmp_path) -> None:
    recorded = {**PrimitiveParams().__dict__, "drive_time": 1.0, "decision_latency": 2.7}
    model = ModelInputs(T=np.zeros((1, 16, 1)), source=None,
                        dataset_seconds_per_transition=None, dataset=str(tmp_path),
                        primitive_params=recorded)
    params, source = primitive_params_for(model, None)
    assert source == "dataset" and params.drive_time == 1.0 and params.decision_latency == 2.7
    same = replace(params, heading_source="odometry")  # heading control may differ
    assert primitive_params_for(model, same)[0] is same
    with pytest.raises(ConfigError, match=r"drive_time 0\.5 vs 1\.0"):
        primitive_params_for(model, replace(params, drive_time=0.5))
    unknown = replace(model, primitive_params={**recorded, "warp_drive": 9})
    with pytest.raises(ConfigError, match=r"unknown primitive parameter.*warp_drive"):
        primitive_params_for(unknown, None)
    assert primitive_params_for(None, None)[1] == "default"
    # an MDP with no record of its primitives: the defaults, with a warning that says so
    unrecorded = replace(model, primitive_params=None, dataset=None)
    with pytest.warns(UserWarning, match="no record of the motion primitives"):
        params, source = primitive_params_for(unrecorded, None)
    assert source == "default" and params == PrimitiveParams()
    # a dataset without primitives (the kinematic simulator) is a record: no warning
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert primitive_params_for(replace(model, primitive_params=None), None)[1] == "default"


def test_dataset_pace_is_read_from_the_estimate_summary(chain, tmp_path) -> None:
    doc = json.loads(chain.mdp.with_suffix(".json").read_text())
    model = load_model(chain.mdp, chain.discretizer, chain.goal_names, chain.goal_masks)
    expected = doc["source"]["simulated_hours"] * 3600 / doc["transitions"]
    assert model.dataset_seconds_per_transition == pytest.approx(expected)
    lone = tmp_path / "mdp.npz"
    shutil.copy(chain.mdp, lone)  # without its summary: pace unknown
    assert load_model(lone, chain.discretizer, chain.goal_names,
                      chain.goal_masks).dataset_seconds_per_transition is None


def _tables_naming(qdir, chain, meta: dict) -> None:
    for g in chain.goal_names:
        save_q_table(qdir / q_file_name(g), chain.Q[g], metadata={"goal": g, **meta})


def test_the_mdp_is_found_from_another_directory_or_its_absence_is_said(
        chain, tmp_path, monkeypatch) -> None:
    # train was run in tmp_path/lab as `train --mdp mdp.npz --out q`: "mdp" is relative to
    # that directory, which the replay (run from elsewhere) cannot know
    lab = tmp_path / "lab"
    lab.mkdir()
    shutil.copy(chain.mdp, lab / "mdp.npz")
    _tables_naming(lab / "q", chain, {"mdp": "mdp.npz",
                                      "mdp_resolved": str(lab / "mdp.npz")})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    qt = load_qtables(lab / "q", chain.goal_names, 41)
    assert discover_mdp(qt) == str(lab / "mdp.npz")
    _tables_naming(tmp_path / "old", chain, {"mdp": "mdp.npz"})  # before mdp_resolved
    qt = load_qtables(tmp_path / "old", chain.goal_names, 41)
    with pytest.warns(UserWarning, match=r"trained on mdp\.npz, which is not found .* --mdp"):
        assert discover_mdp(qt) is None
