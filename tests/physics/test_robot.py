"""The URDF is the single source of the robot's geometry, and matches the published Burger."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yourdfpy

from simlab.assets import resolve
from simlab.errors import ConfigError
from simlab.physics._bullet import BulletClient, pybullet, quiet_stdout
from simlab.physics.arena import LIDAR_PLANE_HEIGHT
from simlab.physics.robot import load_robot_spec
from simlab.physics.urdf_merge import merge_fixed_leaf_links, merged_urdf_path

URDF = resolve("robots", "turtlebot3_burger", ".urdf")


def test_urdf_parses_with_published_dimensions():
    urdf = yourdfpy.URDF.load(str(URDF), build_scene_graph=False, load_meshes=False)
    assert urdf.robot.name == "turtlebot3_burger"
    spec = load_robot_spec()
    assert spec.wheel_radius == pytest.approx(0.033)
    assert spec.wheel_separation == pytest.approx(0.160)
    assert spec.wheel_width == pytest.approx(0.018)
    assert spec.total_mass == pytest.approx(1.0, rel=0.10)
    # footprint 138 x 178 mm (length x width incl. wheels)
    x0, x1, y0, y1 = spec.footprint
    assert (x1 - x0) == pytest.approx(0.138, abs=1e-6)
    assert (y1 - y0) == pytest.approx(0.178, abs=1e-6)
    # LIDAR 0.032 m behind the axle, scan plane ~0.18 m; the arena validator uses the same
    assert spec.lidar_offset[0] == pytest.approx(-0.032)
    assert spec.lidar_offset[2] == pytest.approx(LIDAR_PLANE_HEIGHT)
    assert spec.v_max == 0.22 and spec.w_max == 2.84
    # the wheel speed limit allows both published body limits
    assert spec.v_max / spec.wheel_radius <= spec.wheel_speed_limit
    assert spec.w_max * spec.wheel_separation / 2 / spec.wheel_radius <= spec.wheel_speed_limit


def test_geometry_comes_from_the_urdf(tmp_path):
    """Changing the URDF changes the spec: nothing is duplicated as a literal."""
    text = URDF.read_text().replace('xyz="0 0.080 0.033"', 'xyz="0 0.100 0.033"')
    text = text.replace('xyz="0 -0.080 0.033"', 'xyz="0 -0.100 0.033"')
    text = text.replace('<cylinder radius="0.033" length="0.018"/>',
                        '<cylinder radius="0.040" length="0.018"/>')
    path = tmp_path / "wide.urdf"
    path.write_text(text)
    spec = load_robot_spec(path)
    assert spec.wheel_separation == pytest.approx(0.200)
    assert spec.wheel_radius == pytest.approx(0.040)


def test_missing_urdf_and_missing_wheel_geometry_are_clear_errors(tmp_path):
    with pytest.raises(ConfigError, match=r"nope\.urdf"):
        load_robot_spec(tmp_path / "nope.urdf")
    with pytest.raises(ConfigError, match="unknown robot name 'nope'"):
        load_robot_spec("nope")
    bad = tmp_path / "bad.urdf"
    bad.write_text(URDF.read_text().replace('<cylinder radius="0.033" length="0.018"/>',
                                            '<sphere radius="0.033"/>'))
    with pytest.raises(ConfigError, match=r"bad\.urdf.*wheel_left_link.*cylinder"):
        load_robot_spec(bad)
    with pytest.raises(ConfigError, match="joint 'no_such_joint' not found"):
        load_robot_spec(left_wheel_joint="no_such_joint")


def test_fixed_link_merge_preserves_mass_and_centre_of_mass():
    """The merged base has the summed mass at the mass-weighted centre (parallel axes)."""
    merged = ET.fromstring(merge_fixed_leaf_links(URDF.read_text()))
    assert [j.get("name") for j in merged.findall("joint")] == [
        "wheel_left_joint", "wheel_right_joint"]
    base = next(link for link in merged.findall("link") if link.get("name") == "base_link")
    inertial = base.find("inertial")
    mass = float(inertial.find("mass").get("value"))
    com = [float(v) for v in inertial.find("origin").get("xyz").split()]
    # chassis 0.830 kg at z 0.050, LIDAR 0.114 kg at 0.182 - 0.0095 = 0.1725 (both x -0.032)
    assert mass == pytest.approx(0.944)
    assert com[0] == pytest.approx(-0.032)
    assert com[2] == pytest.approx((0.830 * 0.050 + 0.114 * 0.1725) / 0.944)
    izz = float(inertial.find("inertia").get("izz"))
    assert izz == pytest.approx(0.002657 + 7.0e-05)  # same z axis: no parallel-axis term
    ixx = float(inertial.find("inertia").get("ixx"))
    d1, d2 = com[2] - 0.050, 0.1725 - com[2]
    assert ixx == pytest.approx(0.002753 + 5e-05 + 0.830 * d1**2 + 0.114 * d2**2)


def test_merged_robot_loads_with_the_right_mass_properties():
    with quiet_stdout():
        c = BulletClient(connection_mode=pybullet.DIRECT)
        body = c.loadURDF(str(merged_urdf_path(URDF)), flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
    try:
        assert c.getNumJoints(body) == 2
        info = c.getDynamicsInfo(body, -1)
        assert info[0] == pytest.approx(0.944)
        assert np.allclose(info[3], [-0.032, 0.0, 0.0648], atol=1e-4)
        total = sum(c.getDynamicsInfo(body, link)[0] for link in range(-1, 2))
        assert total == pytest.approx(load_robot_spec().total_mass)
    finally:
        c.disconnect()


def test_swept_radius_is_the_farthest_outline_point():
    spec = load_robot_spec()
    # rear chassis corners (-0.101, +-0.070) are the farthest points of the outline
    assert spec.swept_radius == pytest.approx(math.hypot(0.101, 0.070))
