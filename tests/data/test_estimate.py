"""The empirical MDP: eq. 1.13 with the unvisited rule, entropy in bits, eq. 1.14,
convergence on logs drawn from a known P, coverage, and the ``estimate`` outputs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError, DataError
from simlab.data.dataset import read_dataset
from simlab.data.estimate import (
    count_transitions,
    coverage_report,
    empirical_mdp,
    entropy_bits,
    estimate,
    mean_entropy_per_action,
    transition_matrix,
)


def test_hand_counted_transitions() -> None:
    # S = 3, A = 2. From state 0 with action 1: 3x to 1, 1x to 2. State 2 never visited.
    s = [0, 0, 0, 0, 1, 1]
    a = [1, 1, 1, 1, 0, 0]
    s_next = [1, 1, 1, 2, 1, 0]
    counts = count_transitions(s, a, s_next, n_states=3, n_actions=2)
    assert counts.dtype == np.int64 and counts.shape == (3, 2, 3)
    assert counts[0, 1].tolist() == [0, 3, 1]
    assert counts[1, 0].tolist() == [1, 1, 0]
    assert counts.sum() == 6
    T, visited = transition_matrix(counts)
    np.testing.assert_array_equal(T[0, 1], [0.0, 0.75, 0.25])
    np.testing.assert_array_equal(T[1, 0], [0.5, 0.5, 0.0])
    assert visited.tolist() == [[False, True], [True, False], [False, False]]
    # unvisited pairs are self-loops
    for state, action in [(0, 0), (1, 1), (2, 0), (2, 1)]:
        expected = np.zeros(3)
        expected[state] = 1.0
        np.testing.assert_array_equal(T[state, action], expected)


def test_rows_sum_to_one_on_random_sparse_counts() -> None:
    rng = np.random.default_rng(0)
    counts = rng.integers(0, 4, size=(30, 16, 30)) * (rng.random((30, 16, 1)) < 0.7)
    mdp = empirical_mdp(counts)
    np.testing.assert_allclose(mdp.T.sum(axis=2), 1.0, rtol=0, atol=1e-12)
    assert np.all(mdp.T >= 0)
    assert (~mdp.visited).any() and mdp.visited.any()
    np.testing.assert_array_equal(mdp.visited, counts.sum(axis=2) > 0)
    assert mdp.coverage == pytest.approx(mdp.visited.mean())


@pytest.mark.parametrize("k", [1, 2, 3, 5, 8, 16])
def test_entropy_of_uniform_row_is_log2_k(k: int) -> None:
    row = np.zeros(20)
    row[:k] = 1.0 / k
    assert entropy_bits(row) == pytest.approx(math.log2(k), abs=1e-12)


def test_entropy_of_deterministic_and_unvisited_rows_is_zero() -> None:
    counts = np.zeros((4, 2, 4), dtype=np.int64)
    counts[0, 0, 3] = 17  # deterministic
    counts[1, 0, :2] = 5  # two outcomes, equally likely -> 1 bit
    counts[2, 1] = [1, 1, 2, 0]  # 0.25, 0.25, 0.5 -> 1.5 bits
    mdp = empirical_mdp(counts)
    assert mdp.entropy[0, 0] == 0.0
    assert mdp.entropy[1, 0] == pytest.approx(1.0)
    assert mdp.entropy[2, 1] == pytest.approx(1.5)
    assert mdp.entropy[3, 0] == 0.0 and mdp.entropy[3, 1] == 0.0  # unvisited


def test_mean_entropy_per_action_ignores_unvisited_pairs() -> None:
    entropy = np.array([[1.0, 0.0], [3.0, 0.0], [5.0, 2.0]])
    visited = np.array([[True, False], [True, False], [False, False]])
    got = mean_entropy_per_action(entropy, visited)
    assert got[0] == pytest.approx(2.0)
    assert np.isnan(got[1])


def test_slow_and_fast_means_average_the_action_means() -> None:
    counts = np.zeros((2, 16, 2), dtype=np.int64)
    counts[:, :8, 0] = 4  # slow actions: deterministic, 0 bits
    counts[:, 8:, :] = 3  # fast actions: uniform over 2 states, 1 bit
    mdp = empirical_mdp(counts)
    assert mdp.slow_mean_entropy == 0.0
    assert mdp.fast_mean_entropy == pytest.approx(1.0)


def test_rewards_follow_eq_1_14() -> None:
    counts = np.zeros((3, 2, 3), dtype=np.int64)
    counts[0, 0] = [1, 2, 1]  # 1 of 4 lands in state 2
    counts[1, 1] = [0, 0, 5]
    mdp = empirical_mdp(counts)
    goal = np.array([[False, False, True], [True, True, False]])
    R = mdp.rewards(goal)
    assert R.shape == (2, 3, 2)
    assert R[0, 0, 0] == pytest.approx(0.25) and R[0, 1, 1] == pytest.approx(1.0)
    assert R[1, 0, 0] == pytest.approx(0.75)
    assert R[0, 2, 0] == 0.0  # unvisited pair: no reward observed


def test_estimate_converges_to_a_known_P() -> None:
    """Logs drawn from a known P: every entry within 5 binomial standard errors of P,
    and the mean absolute error shrinks as N grows (about as 1 / sqrt(N))."""
    rng = np.random.default_rng(2024)
    S, A = 6, 4
    P = rng.dirichlet(np.full(S, 0.5), size=(S, A))
    errors = []
    for n in (2_000, 20_000, 200_000):
        s = rng.integers(0, S, n)
        a = rng.integers(0, A, n)
        cum = P[s, a].cumsum(axis=1)
        s_next = np.minimum((rng.random(n)[:, None] > cum).sum(axis=1), S - 1)
        mdp = empirical_mdp(count_transitions(s, a, s_next, S, A))
        n_sa = mdp.n_sa[..., None]
        se = np.sqrt(P * (1 - P) / n_sa) + 1e-12
        assert np.all(np.abs(mdp.T - P) <= 5 * se + 1e-9)
        errors.append(float(np.abs(mdp.T - P).mean()))
    assert errors[0] > errors[1] > errors[2]
    # a tenfold N divides the error by about sqrt(10) = 3.16; allow 2..5
    assert 2.0 < errors[0] / errors[1] < 5.0 and 2.0 < errors[1] / errors[2] < 5.0


def test_coverage_report_counts_every_pair() -> None:
    counts = np.zeros((3, 2, 3), dtype=np.int64)
    counts[0, 0, 1] = 1
    counts[1, 1, 2] = 7
    counts[2, 0, 0] = 150
    report = coverage_report(empirical_mdp(counts))
    assert report["pairs"] == 6 and report["visited_pairs"] == 3
    assert report["unvisited"] == [[0, 1], [1, 0], [2, 1]]
    assert sum(report["n_sa_histogram"].values()) == 6
    assert report["n_sa_histogram"]["0"] == 3 and report["n_sa_histogram"]["1"] == 1
    assert report["n_sa_histogram"]["5-9"] == 1 and report["n_sa_histogram"][">=100"] == 1
    assert report["n_sa_max"] == 150


def test_count_transitions_rejects_out_of_range() -> None:
    with pytest.raises(ValueError, match="s_next"):
        count_transitions([0], [0], [3], n_states=3, n_actions=2)
    with pytest.raises(ValueError, match="a"):
        count_transitions([0], [2], [0], n_states=3, n_actions=2)


# ------------------------------------------------------------------------ estimate()


def test_estimate_of_a_dataset_writes_npz_summary_and_plot(tmp_path: Path,
                                                           kinematic_dataset: Path,
                                                           grid_discretizer) -> None:
    out = tmp_path / "mdp.npz"
    result = estimate(kinematic_dataset, out)
    table = read_dataset(kinematic_dataset)
    with np.load(out, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    S = 25
    assert arrays["counts"].shape == (S, 16, S) and arrays["counts"].dtype == np.int64
    assert arrays["counts"].sum() == table.num_rows
    np.testing.assert_array_equal(
        arrays["counts"],
        count_transitions(table.column("s").to_numpy(), table.column("a").to_numpy(),
                          table.column("s_next").to_numpy(), S))
    np.testing.assert_allclose(arrays["T"].sum(axis=2), 1.0, atol=1e-12)
    assert arrays["visited"].dtype == bool and arrays["entropy"].shape == (S, 16)
    np.testing.assert_array_equal(arrays["centres"], grid_discretizer.centres)
    assert arrays["goal_names"].dtype.kind == "U" and len(arrays["goal_names"]) == 9
    assert arrays["goal_masks"].shape == (9, S) and arrays["goal_masks"].any(axis=1).all()
    # the table's goal "C" at the origin holds the centre state 12 of the 5 x 5 lattice
    c = list(arrays["goal_names"]).index("C")
    assert np.flatnonzero(arrays["goal_masks"][c]).tolist() == [12]
    assert arrays["R"].shape == (9, S, 16)
    np.testing.assert_array_equal(arrays["bounds"], [-0.75, -0.75, 0.75, 0.75])
    summary = json.loads((tmp_path / "mdp.json").read_text())
    assert summary["transitions"] == table.num_rows
    assert summary["coverage"]["fraction_visited"] == pytest.approx(arrays["visited"].mean())
    assert summary["entropy_bits"]["slow_mean"] == pytest.approx(result.mdp.slow_mean_entropy)
    assert len(summary["blocked_fraction_per_action"]) == 16
    assert (tmp_path / "mdp_entropy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_estimate_output_loads_in_the_empirical_mdp_env(tmp_path: Path,
                                                      kinematic_dataset: Path) -> None:
    envs = pytest.importorskip("simlab.envs.empirical_mdp")
    estimate(kinematic_dataset, tmp_path / "mdp.npz", plot=False)
    mdp = envs.load_mdp(tmp_path / "mdp.npz")
    assert list(mdp.goal_names) == ["NW", "N", "NE", "W", "C", "E", "SW", "S", "SE"]
    assert mdp.bounds == (-0.75, -0.75, 0.75, 0.75)


def test_estimate_never_overwrites(tmp_path: Path, kinematic_dataset: Path) -> None:
    out = tmp_path / "mdp.npz"
    (tmp_path / "mdp_entropy.png").write_bytes(b"someone's figure")
    with pytest.raises(ConfigError, match="already exists"):
        estimate(kinematic_dataset, out)
    assert not out.exists() and not (tmp_path / "mdp.json").exists()
    assert (tmp_path / "mdp_entropy.png").read_bytes() == b"someone's figure"
    estimate(kinematic_dataset, out, overwrite=True)
    assert (tmp_path / "mdp_entropy.png").read_bytes()[:4] == b"\x89PNG"


def test_estimate_refuses_output_inside_the_dataset(kinematic_dataset: Path) -> None:
    with pytest.raises(ConfigError, match="inside the dataset"):
        estimate(kinematic_dataset, kinematic_dataset / "mdp.npz")
    assert not (kinematic_dataset / "mdp.npz").exists()


def test_estimate_with_states_of_another_discretizer_is_refused(
        tmp_path: Path, kinematic_dataset: Path, table_states_file: Path) -> None:
    with pytest.raises(DataError, match="discretizer"):
        estimate(kinematic_dataset, tmp_path / "mdp.npz", states=table_states_file)
    assert not (tmp_path / "mdp.npz").exists()


def test_estimate_of_a_corrupted_dataset_names_the_part(tmp_path: Path,
                                                        dataset_copy: Path) -> None:
    part = sorted(dataset_copy.glob("parts/part-*.parquet"))[-1]
    part.write_bytes(part.read_bytes()[:-10])
    with pytest.raises(DataError) as exc:
        estimate(dataset_copy, tmp_path / "mdp.npz")
    assert str(part) in str(exc.value)
    assert not (tmp_path / "mdp.npz").exists()


def test_estimate_needs_exactly_one_source(tmp_path: Path, kinematic_dataset: Path) -> None:
    with pytest.raises(ConfigError):
        estimate(None, tmp_path / "mdp.npz")
    with pytest.raises(ConfigError):
        estimate(kinematic_dataset, tmp_path / "mdp.npz", counts=tmp_path / "c.csv")
    with pytest.raises(ConfigError, match=r"\.npz"):
        estimate(kinematic_dataset, tmp_path / "mdp.txt")


# ------------------------------------------------------------- action sets, unvisited rule


def _count_csv(path: Path, rows: list[tuple[int, int, int, int]]) -> Path:
    path.write_text("s,a,s_next,count\n" + "".join(f"{r[0]},{r[1]},{r[2]},{r[3]}\n"
                                                   for r in rows))
    return path


def test_estimate_records_the_action_set_and_the_unvisited_rule(tmp_path: Path) -> None:
    from simlab.agents.storage import load_npz
    from simlab.base.actions import parse_action_set

    table = _count_csv(tmp_path / "c.csv", [(0, 0, 1, 3), (0, 2, 0, 1), (1, 7, 0, 2)])
    aset = parse_action_set(8, "ccw-east")
    res = estimate(None, tmp_path / "mdp.npz", counts=table, n_states=2, action_set=aset)
    arrays, meta = load_npz(tmp_path / "mdp.npz", ("T",))
    assert meta == {"action_set": aset.to_json(), "unvisited": "mask"}
    assert arrays["T"].shape == (2, 8, 2)
    summary = res.summary
    assert summary["action_set"]["convention"] == "ccw-east"
    # 2 states x 8 actions, 3 visited: 13 masked pairs; no slow/fast split for 8 actions.
    assert summary["masked_pairs"] == 13
    assert summary["entropy_bits"]["slow_mean"] is None
    assert summary["entropy_bits"]["fast_mean"] is None
    # The old rule on request: nothing masked, recorded.
    res = estimate(None, tmp_path / "old.npz", counts=table, n_states=2, action_set=aset,
                   unvisited="self-loop", plot=False)
    assert load_npz(tmp_path / "old.npz")[1]["unvisited"] == "self-loop"
    assert res.summary["masked_pairs"] == 0
    np.testing.assert_array_equal(load_npz(tmp_path / "old.npz")[0]["T"], arrays["T"])
    with pytest.raises(ConfigError, match="unknown rule"):
        estimate(None, tmp_path / "x.npz", counts=table, unvisited="stay")


def test_estimate_of_a_dataset_takes_its_action_set(tmp_path: Path,
                                                    kinematic_dataset: Path) -> None:
    from simlab.base.actions import SIMLAB16, parse_action_set
    from simlab.data.mdp import load_mdp

    estimate(kinematic_dataset, tmp_path / "mdp.npz", plot=False)
    m = load_mdp(tmp_path / "mdp.npz")
    assert m.action_set == SIMLAB16
    with pytest.raises(ConfigError, match="the dataset records 16 actions"):
        estimate(kinematic_dataset, tmp_path / "b.npz", plot=False,
                 action_set=parse_action_set(8, "ccw-east"))
    assert not (tmp_path / "b.npz").exists()


def test_estimate_cli_action_flags(tmp_path: Path, kinematic_dataset: Path, capsys) -> None:
    from simlab.cli import main
    from simlab.data.mdp import load_mdp

    table = _count_csv(tmp_path / "c.csv", [(0, 0, 1, 3), (1, 4, 0, 2)])
    out = tmp_path / "m.npz"
    assert main(["estimate", "--counts", str(table), "--out", str(out), "--n-actions", "8",
                 "--convention", "3,5,0,4,2,6,1,7", "--speed", "fast", "--no-plot"]) == 0
    m = load_mdp(out)
    assert m.action_set.convention == "ccw-east" and m.action_set.speed == "fast"
    assert m.action_set.to_primitive(0) == 8 + 3  # fast RIGHT
    assert "14 untried (s, a) of visited states masked" in capsys.readouterr().out
    # Action flags describe a count table; on a dataset they are refused (exit 2).
    assert main(["estimate", str(kinematic_dataset), "--out", str(tmp_path / "d.npz"),
                 "--convention", "ccw-east"]) == 2
    assert not (tmp_path / "d.npz").exists()
    assert main(["estimate", "--counts", str(table), "--out", str(tmp_path / "e.npz"),
                 "--n-actions", "8", "--convention", "east"]) == 2


def test_estimate_of_an_isir_model_reports_its_fields_and_states_without_data(
        tmp_path: Path) -> None:
    from simlab.base.actions import parse_action_set

    doc = {"transitionActions": [
        {"state": 0, "transitions": [{"action": 0, "state": 1, "prob": 4},
                                     {"action": 2, "state": 0, "prob": 1}]},
        {"state": 1, "transitions": [{"action": 4, "state": 0, "prob": 2}]}],
        "actioncount": 7, "timecount": 812}
    model = tmp_path / "robot_model"  # no extension: sniffed as JSON
    model.write_text(json.dumps(doc))
    res = estimate(None, tmp_path / "mdp.npz", counts=model, n_states=3,
                   action_set=parse_action_set(8, "ccw-east"), plot=False)
    src = res.summary["source"]
    assert src["format"] == "isir" and src["rows"] == 3
    assert src["file_metadata"] == {"actioncount": 7, "timecount": 812}
    # state 2 never appears: all 8 of its actions stay allowed; states 0 and 1 lose their
    # 6 and 7 untried actions
    assert res.summary["states_without_data"] == 1
    assert res.summary["masked_pairs"] == 6 + 7
