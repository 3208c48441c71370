"""A benchmark arm at another default physics rate, for the commands that take the default
(``simlab calibrate``: its candidates' walks; online learning in physics through a world of
the default rate).

:func:`default_rate_env` gives the environment of a subprocess (and of every process it
spawns: a ``sitecustomize`` on its ``PYTHONPATH``) in which
``simlab.physics.rate.DEFAULT_HZ`` is ``hz``: the same code, stepped at another rate. A
benchmark uses it to time the rate before it was a setting (200 Hz) against the default in
one run.
"""

from __future__ import annotations

import os
from pathlib import Path

SITE_CODE = """
import os as _os
if _os.environ.get("SIMLAB_BENCH_DEFAULT_HZ"):
    import simlab.physics.rate as _rate
    _rate.DEFAULT_HZ = float(_os.environ["SIMLAB_BENCH_DEFAULT_HZ"])
"""


def default_rate_env(hz: float, work: Path) -> dict[str, str]:
    """``os.environ`` plus what makes ``hz`` the default rate of a subprocess and of its
    children (a ``sitecustomize`` written under ``work``)."""
    site = work / "rate-site"
    site.mkdir(parents=True, exist_ok=True)
    (site / "sitecustomize.py").write_text(SITE_CODE)
    path = os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "SIMLAB_BENCH_DEFAULT_HZ": f"{hz:g}", "PYTHONPATH": path}
