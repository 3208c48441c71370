"""The standard-library URDF reader gives what yourdfpy gives, without yourdfpy's imports."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.assets import resolve
from simlab.base.errors import ConfigError
from simlab.physics.robot import _parse_urdf


def test_parse_matches_yourdfpy() -> None:
    yourdfpy = pytest.importorskip("yourdfpy")
    path = resolve("robots", "turtlebot3_burger", ".urdf")
    ref = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False).robot
    got = _parse_urdf(path)
    assert got.name == ref.name
    assert [j.name for j in got.joints] == [j.name for j in ref.joints]
    for a, b in zip(got.joints, ref.joints, strict=True):
        assert (a.parent, a.child) == (b.parent, b.child)
        np.testing.assert_allclose(a.origin, b.origin, rtol=0, atol=1e-15)
        if b.limit is not None:
            assert (a.limit.effort, a.limit.velocity) == (b.limit.effort, b.limit.velocity)
    for a, b in zip(got.links, ref.links, strict=True):
        assert a.name == b.name
        assert (a.inertial is None) == (b.inertial is None)
        if b.inertial is not None:
            assert a.inertial.mass == b.inertial.mass
        for mine, theirs in ((a.visuals, b.visuals), (a.collisions, b.collisions)):
            assert len(mine) == len(theirs)
            for m, t in zip(mine, theirs, strict=True):
                np.testing.assert_allclose(m.origin, t.origin, rtol=0, atol=1e-15)
                if t.geometry.box is not None:
                    assert list(m.geometry.box.size) == list(t.geometry.box.size)
                if t.geometry.cylinder is not None:
                    assert m.geometry.cylinder.radius == t.geometry.cylinder.radius
                    assert m.geometry.cylinder.length == t.geometry.cylinder.length


def test_rpy_origin_and_bad_xml(tmp_path) -> None:
    good = tmp_path / "r.urdf"
    good.write_text('<robot name="r"><link name="a"/><link name="b"/>'
                    '<joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
                    '<origin xyz="1 2 3" rpy="0 0 1.5707963267948966"/></joint></robot>')
    j = _parse_urdf(good).joints[0]
    np.testing.assert_allclose(j.origin[:3, 3], [1, 2, 3])
    np.testing.assert_allclose(j.origin[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='r'><link name='a'>")
    with pytest.raises(ConfigError, match=r"bad\.urdf.*cannot parse URDF"):
        _parse_urdf(bad)


def test_loading_the_robot_imports_no_yourdfpy_calibration_guard() -> None:
    # the reason the reader is ours (benchmarks/urdf_reader.py): yourdfpy and trimesh cost
    # every fresh process (walk workers, envs) 0.7-1.0 s of imports
    import subprocess
    import sys

    code = ("import sys\n"
            "from simlab.physics.robot import load_robot_spec\n"
            "from simlab.physics.urdf_merge import merged_urdf_path\n"
            "merged_urdf_path(load_robot_spec().urdf_path)\n"
            "print(sorted(m for m in ('yourdfpy', 'trimesh', 'lxml') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
