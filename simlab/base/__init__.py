"""The base layer: what every other simlab package may use, and which uses none of them.

* :mod:`~simlab.base.errors` — the error classes (each names the file or field and the fix)
  and :func:`~simlab.base.errors.warn`;
* :mod:`~simlab.base.validation` — checks of user values and files, one per kind;
* :mod:`~simlab.base.options` — the documented command-config fields and the seed range;
* :mod:`~simlab.base.io` — atomic writes and the output transaction (nothing half-written);
* :mod:`~simlab.base.actions`, :mod:`~simlab.base.directions` — the 16 motion primitives
  and the robot-frame directions;
* :mod:`~simlab.base.assets` — the built-in robots and arenas;
* :mod:`~simlab.base.parallel` — one pool for every parallel loop (processes, or Ray);
* :mod:`~simlab.base.guards` — the memory-estimate guard (refuse before allocating);
* :mod:`~simlab.base.statecheck` — states that belong to their arena, fingerprints where
  files meet;
* :mod:`~simlab.base.lazy`, :mod:`~simlab.base.fingerprint`,
  :mod:`~simlab.base._numba_cache` — lazy exports, source fingerprints and the numba cache
  directory per source version.

The layers above it are declared in ``tests/core/test_layering.py``.
"""
