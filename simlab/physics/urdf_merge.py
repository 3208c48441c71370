"""Fold fixed-joint links into their parents before PyBullet loads a URDF.

Two kinds are folded: leaf links (sensor housings, ROS frames such as ``imu_link``) and the
child of a bare root frame (REP-105's ``base_footprint`` with ``base_link`` under it, as in
the ROBOTIS TurtleBot3 description): the multibody's base is then the root frame, on the
floor, carrying the chassis, and the wheels are its only links.

Every link of a PyBullet multibody costs solver time each step even when welded by a fixed
joint: folding the LIDAR housing of the TurtleBot3 into the base makes a step about 9 %
cheaper with identical dynamics. PyBullet's own ``URDF_MERGE_FIXED_LINKS`` is not usable:
it ignores the parent link's ``<inertial><origin>`` and so misplaces the merged centre of
mass (measured: (-0.004, 0, 0.022) m instead of (-0.032, 0, 0.064) m for the Burger), which
takes most of the load off the caster.

The merge here works on the XML, so Bullet's ``<contact>`` extension elements survive; it
moves the child's ``<visual>`` and ``<collision>`` elements to the parent (origins composed
with the joint origin) and combines the inertials exactly (mass-weighted centre of mass,
parallel-axis theorem). A leaf's own ``<contact>`` friction would be lost in a parent with
shapes of its own, so such leaves are kept; a bare parent takes its child's ``<contact>``. The source URDF stays the single source of truth: geometry is read
from it (:func:`simlab.physics.robot.load_robot_spec`, with the same standard-library XML
parser: yourdfpy would cost a fresh process 0.7-1.0 s of imports, ``benchmarks/urdf_reader.py``;
it also drops the ``<contact>`` elements this merge must keep) and the merged copy is derived
at load time.
"""

from __future__ import annotations

import hashlib
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from simlab.base.io import atomic_write_text


def _rpy_matrix(rpy: NDArray[np.float64]) -> NDArray[np.float64]:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _matrix_rpy(m: NDArray[np.float64]) -> NDArray[np.float64]:
    pitch = np.arcsin(np.clip(-m[2, 0], -1.0, 1.0))
    if abs(np.cos(pitch)) < 1e-9:  # gimbal lock: put everything in yaw
        return np.array([0.0, pitch, np.arctan2(-m[0, 1], m[1, 1])])
    return np.array([np.arctan2(m[2, 1], m[2, 2]), pitch, np.arctan2(m[1, 0], m[0, 0])])


def _origin(elem: ET.Element | None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(translation (3,), rotation (3,3)) of an element's <origin> child (identity if none)."""
    o = None if elem is None else elem.find("origin")
    xyz = np.zeros(3) if o is None else np.array([float(v) for v in o.get("xyz", "0 0 0").split()])
    rpy = np.zeros(3) if o is None else np.array([float(v) for v in o.get("rpy", "0 0 0").split()])
    return xyz, _rpy_matrix(rpy)


def _set_origin(elem: ET.Element, xyz: NDArray[np.float64], rot: NDArray[np.float64]) -> None:
    o = elem.find("origin")
    if o is None:
        o = ET.Element("origin")
        elem.insert(0, o)
    o.set("xyz", " ".join(f"{v:.10g}" for v in xyz))
    o.set("rpy", " ".join(f"{v:.10g}" for v in _matrix_rpy(rot)))


def _inertia(inertial: ET.Element) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """(mass, centre of mass (3,), inertia tensor about the COM in the link frame (3,3))."""
    mass = float(inertial.find("mass").get("value"))
    xyz, rot = _origin(inertial)
    i = inertial.find("inertia")
    g = {k: float(i.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    local = np.array([[g["ixx"], g["ixy"], g["ixz"]],
                      [g["ixy"], g["iyy"], g["iyz"]],
                      [g["ixz"], g["iyz"], g["izz"]]])
    return mass, xyz, rot @ local @ rot.T


def _combine(parts: list[tuple[float, NDArray[np.float64], NDArray[np.float64]]]):
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass
    tensor = np.zeros((3, 3))
    for m, c, inertia in parts:
        d = c - com
        tensor += inertia + m * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return mass, com, tensor


def _bare(link: ET.Element) -> bool:
    """A link that is only a frame: no inertial, visual, collision or contact element."""
    return all(link.find(tag) is None for tag in ("inertial", "visual", "collision", "contact"))


def _foldable(joint: ET.Element, links: dict[str, ET.Element],
              parents: set[str | None]) -> bool:
    """A fixed joint whose child can be folded into its parent: a leaf without its own
    ``<contact>`` friction, or any child of a bare parent (a ROS root frame such as
    ``base_footprint``: the child's contents, friction included, move up unchanged)."""
    if joint.get("type") != "fixed":
        return False
    child = links[joint.find("child").get("link")]
    if _bare(links[joint.find("parent").get("link")]):
        return True
    return child.get("name") not in parents and child.find("contact") is None


def merge_fixed_leaf_links(xml_text: str) -> str:
    """Return URDF text with fixed-joint links folded into their parents (leaves, and the
    child of a bare root), until none is left."""
    root = ET.fromstring(xml_text)
    links = {link.get("name"): link for link in root.findall("link")}
    while True:
        joints = root.findall("joint")
        parents = {j.find("parent").get("link") for j in joints}
        joint = next((j for j in joints if _foldable(j, links, parents)), None)
        if joint is None:
            return ET.tostring(root, encoding="unicode")
        child_name = joint.find("child").get("link")
        child = links.pop(child_name)
        parent_name = joint.find("parent").get("link")
        parent = links[parent_name]
        j_xyz, j_rot = _origin(joint)
        for tag in ("visual", "collision"):
            for elem in child.findall(tag):
                e_xyz, e_rot = _origin(elem)
                _set_origin(elem, j_xyz + j_rot @ e_xyz, j_rot @ e_rot)
                child.remove(elem)
                parent.append(elem)
        contact = child.find("contact")
        if contact is not None:  # only when the parent is bare (see _foldable)
            parent.append(contact)
        for grandchild in joints:  # the child's own joints now start at the parent
            if grandchild.find("parent").get("link") == child_name:
                g_xyz, g_rot = _origin(grandchild)
                _set_origin(grandchild, j_xyz + j_rot @ g_xyz, j_rot @ g_rot)
                grandchild.find("parent").set("link", parent_name)
        c_in, p_in = child.find("inertial"), parent.find("inertial")
        if c_in is not None:
            m, c, inertia = _inertia(c_in)
            moved = (m, j_xyz + j_rot @ c, j_rot @ inertia @ j_rot.T)
            parts = [moved] if p_in is None else [_inertia(p_in), moved]
            mass, com, tensor = _combine(parts)
            if p_in is not None:
                parent.remove(p_in)
            new = ET.SubElement(parent, "inertial")
            ET.SubElement(new, "origin", xyz=" ".join(f"{v:.10g}" for v in com), rpy="0 0 0")
            ET.SubElement(new, "mass", value=f"{mass:.10g}")
            ET.SubElement(new, "inertia", ixx=f"{tensor[0, 0]:.10g}", ixy=f"{tensor[0, 1]:.10g}",
                          ixz=f"{tensor[0, 2]:.10g}", iyy=f"{tensor[1, 1]:.10g}",
                          iyz=f"{tensor[1, 2]:.10g}", izz=f"{tensor[2, 2]:.10g}")
        root.remove(joint)
        root.remove(child)


def merged_urdf_path(source: str | Path) -> Path:
    """Path of the merged copy of ``source``, written once into the temp dir (cached by hash).

    Mesh paths are not rewritten, so only primitive-shape URDFs (like ours) are supported;
    a URDF referencing meshes is returned unchanged.
    """
    source = Path(source)
    text = source.read_text(encoding="utf-8")
    if "<mesh" in text:
        return source
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    out = Path(tempfile.gettempdir()) / f"simlab-{source.stem}-{digest}.urdf"
    if not out.exists():
        atomic_write_text(out, merge_fixed_leaf_links(text))
    return out
