"""simlab: robot reinforcement learning for social navigation.

Two halves share one agent library (:mod:`simlab.agents`):

* the physics half (:mod:`simlab.physics`, :mod:`discretize`, :mod:`simlab.data`,
  :mod:`simlab.replay`): a PyBullet TurtleBot3 Burger in a table arena, a random-walk
  transition dataset, the empirical MDP, and closed-loop replay of learned policies;
* the tabular half (:mod:`simlab.visitlab`): the "Visit the lab" human-robot
  interaction simulation.

Importing :mod:`simlab` registers the Gymnasium environments (``simlab/...-v0``) as soon
as Gymnasium is imported (at once if it already is; :func:`simlab.envs.register_when_imported`),
so importing simlab does not import Gymnasium; the heavy modules are imported only when an
environment is made.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from simlab.base._numba_cache import use_versioned_cache_dir as _use_versioned_cache_dir
from simlab.envs import register_when_imported as _register_when_imported

# before anything imports numba: one cache directory per source version (simlab.base._numba_cache)
_use_versioned_cache_dir()

try:
    __version__ = version("simlab")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+src"

_register_when_imported()

__all__ = ["__version__"]
