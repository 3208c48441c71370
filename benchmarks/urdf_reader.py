"""What reading the robot's URDF through yourdfpy would cost a fresh process.

simlab reads the URDF with the standard library's XML parser (``simlab.physics.robot``
reads the robot's parts, ``simlab.physics.urdf_merge`` rewrites the XML for PyBullet).
Every walk worker, replay baseline and env is a fresh process that loads the robot, so the
import is paid once per process. The script prints, median of 5 fresh interpreters, the
import time of ``xml.etree.ElementTree`` and of ``yourdfpy`` (which imports trimesh and
lxml), then the time of one parse of the TurtleBot3 Burger by each reader.

Run: ``python benchmarks/urdf_reader.py``.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import timeit

from simlab.base.assets import resolve
from simlab.physics.robot import _parse_urdf

_IMPORT = ("import time; t = time.perf_counter(); import {module}; "
           "print(time.perf_counter() - t)")


def import_seconds(module: str, repeats: int = 5) -> float:
    """Median seconds of ``import module`` in a fresh interpreter."""
    times = [float(subprocess.run([sys.executable, "-c", _IMPORT.format(module=module)],
                                  capture_output=True, text=True, check=True).stdout)
             for _ in range(repeats)]
    return statistics.median(times)


def main() -> None:
    for module in ("xml.etree.ElementTree", "yourdfpy"):
        print(f"import {module:24s} {import_seconds(module) * 1e3:8.1f} ms")
    import yourdfpy

    path = resolve("robots", "turtlebot3_burger", ".urdf")
    n = 50
    ours = min(timeit.repeat(lambda: _parse_urdf(path), number=n, repeat=3)) / n
    theirs = min(timeit.repeat(
        lambda: yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False),
        number=n, repeat=3)) / n
    print(f"parse, standard library        {ours * 1e3:8.2f} ms")
    print(f"parse, yourdfpy.URDF.load      {theirs * 1e3:8.2f} ms")


if __name__ == "__main__":
    main()
