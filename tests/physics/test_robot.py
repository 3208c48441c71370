"""The URDF is the single source of the robot's geometry, and matches the published Burger."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yourdfpy

from simlab.base.assets import resolve
from simlab.base.errors import ConfigError
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
    text = URDF.read_text().replace('xyz="0 0.080 0.023"', 'xyz="0 0.100 0.023"')
    text = text.replace('xyz="0 -0.080 0.023"', 'xyz="0 -0.100 0.023"')
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
    assert [link.get("name") for link in merged.findall("link")] == [
        "base_footprint", "wheel_left_link", "wheel_right_link"]
    base = merged.find("link")  # the root frame took base_link's and base_scan's contents
    inertial = base.find("inertial")
    mass = float(inertial.find("mass").get("value"))
    com = [float(v) for v in inertial.find("origin").get("xyz").split()]
    # in the floor frame: chassis 0.830 kg at z 0.050, LIDAR 0.114 kg at 0.182 - 0.0095 =
    # 0.1725 (both x -0.032)
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


def test_urdf_tree_is_rooted_at_base_footprint_with_the_physics_in_place():
    """ROBOTIS's frame tree (base_footprint -> base_link 0.010 m up), while every shape and
    mass sits where it did when base_link was the root on the floor."""
    urdf = yourdfpy.URDF.load(str(URDF), build_scene_graph=True, load_meshes=False)
    assert urdf.base_link == "base_footprint"
    parent = {j.child: j.parent for j in urdf.robot.joints}
    assert parent["base_link"] == "base_footprint"
    for child in ("wheel_left_link", "wheel_right_link", "base_scan", "caster_back_link",
                  "imu_link"):
        assert parent[child] == "base_link"
    up = urdf.get_transform("base_link", "base_footprint")
    np.testing.assert_allclose(up[:3, 3], [0.0, 0.0, 0.010], atol=1e-12)
    spec = load_robot_spec()
    assert spec.root_link == "base_footprint" and spec.base_link == "base_link"
    assert spec.base_link_offset == pytest.approx((0.0, 0.0, 0.010))
    # wheels and caster touch the floor (z = 0 of base_footprint), the scan plane is where
    # the arena validator expects it
    for wheel in ("wheel_left_link", "wheel_right_link"):
        z = urdf.get_transform(wheel, "base_footprint")[2, 3]
        assert z == pytest.approx(spec.wheel_radius)
    base = urdf.link_map["base_link"]
    caster = next(c for c in base.collisions if c.geometry.sphere is not None)
    assert (up @ caster.origin)[2, 3] == pytest.approx(caster.geometry.sphere.radius)
    chassis = next(c for c in base.collisions if c.geometry.box is not None)
    assert (up @ chassis.origin)[2, 3] - chassis.geometry.box.size[2] / 2 == pytest.approx(0.010)
    assert urdf.get_transform("base_scan", "base_footprint")[2, 3] == pytest.approx(
        LIDAR_PLANE_HEIGHT)
    assert spec.wheel_radius == 0.033 and spec.wheel_separation == pytest.approx(0.160)


def test_folding_under_a_bare_root_composes_rotations_and_keeps_friction():
    """A bare root's fixed child (turned 90 degrees, 0.1 m up) folds into the root: its
    shapes, inertial and friction move up, and its own joints start at the root with the
    composed origin."""
    text = """<robot name="r">
      <link name="root"/>
      <joint name="up" type="fixed"><parent link="root"/><child link="body"/>
        <origin xyz="0 0 0.1" rpy="0 0 1.5707963267948966"/></joint>
      <link name="body">
        <contact><lateral_friction value="0.25"/></contact>
        <collision><origin xyz="1 0 0"/><geometry><box size="1 2 3"/></geometry></collision>
        <inertial><origin xyz="1 0 0"/><mass value="2"/>
          <inertia ixx="1" ixy="0" ixz="0" iyy="2" iyz="0" izz="3"/></inertial>
      </link>
      <joint name="spin" type="continuous"><parent link="body"/><child link="wheel"/>
        <origin xyz="0 1 0"/><axis xyz="0 1 0"/></joint>
      <link name="wheel"><inertial><mass value="1"/>
        <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
    </robot>"""
    merged = ET.fromstring(merge_fixed_leaf_links(text))
    assert [link.get("name") for link in merged.findall("link")] == ["root", "wheel"]
    root = merged.find("link")
    assert float(root.find("contact/lateral_friction").get("value")) == 0.25
    box = [float(v) for v in root.find("collision/origin").get("xyz").split()]
    np.testing.assert_allclose(box, [0.0, 1.0, 0.1], atol=1e-9)  # x of body = y of root
    com = [float(v) for v in root.find("inertial/origin").get("xyz").split()]
    np.testing.assert_allclose(com, [0.0, 1.0, 0.1], atol=1e-9)
    inertia = root.find("inertial/inertia")
    # the body's x and y axes swap under the 90-degree turn
    assert float(inertia.get("ixx")) == pytest.approx(2.0)
    assert float(inertia.get("iyy")) == pytest.approx(1.0)
    joint = merged.find("joint")
    assert joint.find("parent").get("link") == "root"
    xyz = [float(v) for v in joint.find("origin").get("xyz").split()]
    np.testing.assert_allclose(xyz, [-1.0, 0.0, 0.1], atol=1e-9)  # body's +y is root's -x
    rpy = [float(v) for v in joint.find("origin").get("rpy").split()]
    np.testing.assert_allclose(rpy, [0.0, 0.0, math.pi / 2], atol=1e-9)


def test_a_urdf_that_is_not_one_tree_is_refused_naming_the_file(tmp_path):
    """Positions are composed from the root: two roots leave them undefined."""
    text = URDF.read_text().replace('<link name="imu_link"/>',
                                    '<link name="imu_link"/>\n  <link name="stray"/>')
    path = tmp_path / "two_roots.urdf"
    path.write_text(text)
    with pytest.raises(ConfigError, match=r"two_roots\.urdf.*one tree.*stray"):
        load_robot_spec(path)
