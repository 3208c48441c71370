"""URDF frames for ROS tools (base_footprint, caster_back_link, imu_link) without physics.

base_footprint is the tree's root, base_link 0.010 m above it (ROBOTIS's base_joint); the
leaf frames hang from base_link.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from simlab.physics.robot import load_robot_spec
from simlab.physics.urdf_merge import merge_fixed_leaf_links

#: ROBOTIS turtlebot3_description (turtlebot3_burger.urdf): caster_back_joint and imu_joint
FRAMES = {"caster_back_link": (-0.081, 0.0, -0.005), "imu_link": (-0.032, 0.0, 0.068)}


def _text() -> str:
    from pathlib import Path

    return Path(load_robot_spec().urdf_path).read_text()


def test_ros_frames_hang_from_base_link_as_in_the_turtlebot3_description() -> None:
    import yourdfpy

    robot = yourdfpy.URDF.load(str(load_robot_spec().urdf_path), load_meshes=False)
    links = {link.name for link in robot.robot.links}
    assert {"base_footprint", "base_link", "base_scan", *FRAMES} <= links
    root = next(j for j in robot.robot.joints if j.child == "base_link")
    assert root.parent == "base_footprint" and root.type == "fixed"
    np.testing.assert_allclose(root.origin[:3, 3], (0.0, 0.0, 0.010))
    for name, xyz in FRAMES.items():
        joint = next(j for j in robot.robot.joints if j.child == name)
        assert joint.parent == "base_link" and joint.type == "fixed"
        np.testing.assert_allclose(joint.origin[:3, 3], xyz)


def test_frames_are_folded_away_so_the_physics_is_unchanged() -> None:
    root = ET.fromstring(_text())
    for joint in [j for j in root.findall("joint") if j.find("child").get("link") in FRAMES]:
        root.remove(joint)
    for link in [x for x in root.findall("link") if x.get("name") in FRAMES]:
        root.remove(link)
    without = ET.tostring(root, encoding="unicode")

    def canon(xml: str) -> str:
        return ET.canonicalize(merge_fixed_leaf_links(xml), strip_text=True)

    assert canon(_text()) == canon(without)  # the loaded multibody is identical
    assert not any(name in canon(_text()) for name in FRAMES)
