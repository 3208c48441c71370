"""Options of ``simlab online --arena`` that would do nothing are refused, naming them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.faults.conftest import assert_refused, run_cli


@pytest.mark.parametrize(("extra", "needles"), [
    ("--mcl-map stale", ("mcl_map", "--mcl-map stale", "--pose-source truth",
                         "add --pose-source mcl or drop --mcl-map")),
    ("--mcl-map stale --pose-source truth", ("mcl_map", "--pose-source mcl")),
])
def test_the_filters_map_option_without_the_filter_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str,
        needles: tuple[str, ...]) -> None:
    """``--mcl-map`` says what the particle filter's map does after a box: with the truth
    as pose source there is no filter (``--map`` is refused the same way)."""
    from discretize.voronoi import Discretizer

    g = np.linspace(-0.6, 0.6, 5)
    states = Discretizer(centres=np.array([(x, y) for y in g for x in g])).save(
        tmp_path / "s.json")
    res = run_cli(f"online --arena table --states {states} --goal 12 --start-states 0 "
                  f"--decisions 4 --seeds 1 --workers 1 --no-plots --out {tmp_path}/o "
                  f"{extra}".split(), capsys)
    assert_refused(res, *needles)
    assert not (tmp_path / "o").exists()
