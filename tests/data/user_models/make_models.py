"""Writes the furniture test models of this folder, each as SDFormat and as URDF.

Plain XML written by hand-made templates (no mmlearn code): these stand for files a user
brings. Run ``python make_models.py`` in this folder to rewrite them.

* ``wall_cabinet``: 0.40 x 0.55 m door hinged on the left (as seen from the front), bar
  handle (cylinder on two box posts), joint limits [0, 2.0] rad.
* ``wardrobe``: a larger 0.55 x 0.80 m door hinged on the right, a knob (sphere on a stem),
  its joint opening towards negative angles (limits [-1.9, 0]), and the model's origin at
  an odd place (its base link's frame 0.7 m to the side, 0.3 m up and turned 2 rad).
* ``drawer``: a 0.45 x 0.18 m drawer (box with front panel) on a prismatic joint with
  limits [0, 0.40] m, a horizontal bar handle; the URDF welds it to its world.
* ``light_door``: a light (0.6 kg) 0.35 x 0.50 m door hinged on the left, with a thin
  cylinder handle (radius 6 mm) and joint damping 2 N*m*s/rad, without joint limits
  (continuous in URDF).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def rotz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rpy(R):
    """roll pitch yaw (x-y-z fixed axes) of R."""
    pitch = math.asin(-max(-1.0, min(1.0, R[2, 0])))
    roll = math.atan2(R[2, 1], R[2, 2])
    yaw = math.atan2(R[1, 0], R[0, 0])
    return roll, pitch, yaw


def f(v):
    return " ".join(f"{x:.6g}" for x in v)


class Model:
    """Links (pose in the model frame, shapes in the link frame), joints at the child's
    origin."""

    def __init__(self, name, T=(np.eye(3), np.zeros(3))):
        self.name, self.T, self.links, self.joints = name, T, [], []

    def link(self, name, origin, mass):
        R0, t0 = self.T
        lk = {"name": name, "R": R0, "t": R0 @ np.asarray(origin, float) + t0, "mass": mass,
              "shapes": []}
        self.links.append(lk)
        return lk

    @staticmethod
    def shape(lk, name, kind, size, xyz, rot=(0, 0, 0)):
        lk["shapes"].append((name, kind, size, np.asarray(xyz, float), rot))

    def joint(self, name, kind, parent, child, axis=(0, 0, 1), limits=None, damping=0.0):
        self.joints.append((name, kind, parent, child, np.asarray(axis, float), limits,
                            damping))

    def _lk(self, name):
        return next(lk for lk in self.links if lk["name"] == name)

    # -- SDFormat -----------------------------------------------------------------------
    def sdf(self, weld=False):
        out = ['<?xml version="1.0"?>', '<sdf version="1.9">', f'  <model name="{self.name}">']
        for lk in self.links:
            out.append(f'    <link name="{lk["name"]}">')
            out.append(f'      <pose>{f(lk["t"])} {f(rpy(lk["R"]))}</pose>')
            out += self._inertial_sdf(lk)
            for nm, kind, size, xyz, rot in lk["shapes"]:
                g = self._geom_sdf(kind, size)
                for tag in ("collision", "visual"):
                    out.append(f'      <{tag} name="{nm}_{tag[:3]}"><pose>{f(xyz)} {f(rot)}'
                               f'</pose><geometry>{g}</geometry></{tag}>')
            out.append('    </link>')
        for nm, kind, parent, child, axis, limits, damping in self.joints:
            out.append(f'    <joint name="{nm}" type="{kind}"><parent>{parent}</parent>'
                       f'<child>{child}</child>')
            if kind != "fixed":
                ax = self._lk(child)["R"].T @ axis  # expressed in the joint (child) frame
                lim = (f'<limit><lower>{limits[0]}</lower><upper>{limits[1]}</upper></limit>'
                       if limits else "")
                out.append(f'      <axis><xyz>{f(ax)}</xyz>{lim}<dynamics><damping>{damping}'
                           f'</damping></dynamics></axis>')
            out.append('    </joint>')
        if weld:
            out.append(f'    <joint name="to_world" type="fixed"><parent>world</parent>'
                       f'<child>{self.links[0]["name"]}</child></joint>')
        out += ['  </model>', '</sdf>', '']
        return "\n".join(out)

    @staticmethod
    def _geom_sdf(kind, size):
        if kind == "box":
            return f"<box><size>{f(size)}</size></box>"
        if kind == "cylinder":
            return f"<cylinder><radius>{size[0]}</radius><length>{size[1]}</length></cylinder>"
        return f"<sphere><radius>{size[0]}</radius></sphere>"

    @staticmethod
    def _inertial_sdf(lk):
        m = lk["mass"]
        i = m * 0.02
        return [f'      <inertial><mass>{m}</mass><inertia><ixx>{i}</ixx><iyy>{i}</iyy>'
                f'<izz>{i}</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>']

    # -- URDF ---------------------------------------------------------------------------
    def urdf(self, weld=False):
        out = ['<?xml version="1.0"?>', f'<robot name="{self.name}">']
        if weld:
            out.append('  <link name="world"/>')
        for lk in self.links:
            m = lk["mass"]
            i = m * 0.02
            out.append(f'  <link name="{lk["name"]}">')
            out.append(f'    <inertial><mass value="{m}"/><inertia ixx="{i}" iyy="{i}" '
                       f'izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial>')
            for nm, kind, size, xyz, rot in lk["shapes"]:
                g = self._geom_urdf(kind, size)
                for tag in ("collision", "visual"):
                    out.append(f'    <{tag} name="{nm}_{tag[:3]}"><origin xyz="{f(xyz)}" '
                               f'rpy="{f(rot)}"/><geometry>{g}</geometry></{tag}>')
            out.append('  </link>')
        root = self.links[0]
        if weld:  # the file's world = the model frame
            out.append(f'  <joint name="to_world" type="fixed"><parent link="world"/><child '
                       f'link="{root["name"]}"/><origin xyz="{f(root["t"])}" '
                       f'rpy="{f(rpy(root["R"]))}"/></joint>')
        elif any(abs(v) > 1e-12 for v in root["t"]) or not np.allclose(root["R"], np.eye(3)):
            raise ValueError("a floating URDF root must sit at the model frame")
        for nm, kind, parent, child, axis, limits, damping in self.joints:
            P, C = self._lk(parent), self._lk(child)
            R = P["R"].T @ C["R"]
            t = P["R"].T @ (C["t"] - P["t"])
            if kind == "revolute" and limits is None:
                kind = "continuous"
            out.append(f'  <joint name="{nm}" type="{kind}"><parent link="{parent}"/>'
                       f'<child link="{child}"/><origin xyz="{f(t)}" rpy="{f(rpy(R))}"/>')
            if kind != "fixed":
                out.append(f'    <axis xyz="{f(C["R"].T @ axis)}"/>'
                           f'<dynamics damping="{damping}"/>')
                if limits:
                    out.append(f'    <limit lower="{limits[0]}" upper="{limits[1]}" '
                               f'effort="100" velocity="10"/>')
            out.append('  </joint>')
        out += ['</robot>', '']
        return "\n".join(out)

    @staticmethod
    def _geom_urdf(kind, size):
        if kind == "box":
            return f'<box size="{f(size)}"/>'
        if kind == "cylinder":
            return f'<cylinder radius="{size[0]}" length="{size[1]}"/>'
        return f'<sphere radius="{size[0]}"/>'


def carcass(m, W, H, D, bottom, origin=(0, 0, 0), name="body"):
    """A carcass link: its front opening's lower centre at ``origin`` + (0, 0, bottom), the
    front face the plane x = 0 of the link, depth along -x."""
    lk = m.link(name, origin, 25.0)
    t = 0.02
    cw, ch = W + 2 * t + 0.01, bottom + H + t
    for nm, size, xyz in (("top", (D, cw, t), (-D / 2, 0, ch - t / 2)),
                          ("floor", (D, cw, t), (-D / 2, 0, bottom - t / 2)),
                          ("left", (D, t, ch), (-D / 2, -cw / 2 + t / 2, ch / 2)),
                          ("right", (D, t, ch), (-D / 2, cw / 2 - t / 2, ch / 2)),
                          ("back", (t, cw, ch), (-D + t / 2, 0, ch / 2)),
                          ("plinth", (2 * t, cw, bottom), (-t, 0, bottom / 2))):
        m.shape(lk, nm, "box", size, xyz)
    return lk


def bar(m, lk, centre, vertical, length=0.20, r=0.01, standoff=0.06, kind="cylinder"):
    """A bar handle at ``centre`` (its axis ``standoff`` in front of the surface behind it)
    with two posts back to that surface."""
    cx, cy, cz = centre
    rot = (0, 0, 0) if vertical else (math.pi / 2, 0, 0)
    m.shape(lk, "handle_bar", kind, (r, length), centre, rot)
    for k, s in (("a", -1), ("b", 1)):
        off = (0, 0, s * (length / 2 - 0.015)) if vertical else (0, s * (length / 2 - 0.015), 0)
        m.shape(lk, f"handle_post_{k}", "box", (standoff, 0.012, 0.012),
                (cx - standoff / 2, cy + off[1], cz + off[2]))


def wall_cabinet():
    W, H, D, b = 0.40, 0.55, 0.35, 0.35
    m = Model("wall_cabinet")
    carcass(m, W, H, D, b)
    door = m.link("door", (0.014, -W / 2, b), 3.0)   # hinge: the front's left edge (-y)
    m.shape(door, "panel", "box", (0.02, W - 0.006, H - 0.006), (0, W / 2, H / 2))
    bar(m, door, (0.01 + 0.06, W - 0.06, 0.33), vertical=True)
    m.joint("door_hinge", "revolute", "body", "door", axis=(0, 0, -1), limits=(0, 2.0),
            damping=0.5)
    return m


def wardrobe():
    W, H, D, b = 0.55, 0.80, 0.50, 0.20
    m = Model("wardrobe", (rotz(2.0), np.array([0.7, -0.4, 0.3])))
    carcass(m, W, H, D, b)
    door = m.link("door", (0.014, W / 2, b), 5.0)    # hinge: the front's right edge (+y)
    m.shape(door, "panel", "box", (0.02, W - 0.006, H - 0.006), (0, -W / 2, H / 2))
    knob = (0.01 + 0.075, -(W - 0.07), 0.42)
    m.shape(door, "knob", "sphere", (0.022,), knob)
    m.shape(door, "knob_stem", "cylinder", (0.008, 0.06), (0.01 + 0.03, knob[1], knob[2]),
            (0, math.pi / 2, 0))
    # axis -z: positive angles would swing the door into the carcass; it opens negative
    m.joint("left_wing", "revolute", "body", "door", axis=(0, 0, -1), limits=(-1.9, 0),
            damping=1.0)
    return m


def drawer():
    W, H, D, b = 0.45, 0.18, 0.50, 0.62
    m = Model("drawer_unit")
    carcass(m, W, H, D, b)
    dr = m.link("drawer", (0.014, 0, b), 2.5)
    m.shape(dr, "front", "box", (0.02, W - 0.006, H - 0.006), (0, 0, H / 2))
    m.shape(dr, "bottom", "box", (D - 0.06, W - 0.04, 0.01), (-(D - 0.06) / 2, 0, 0.015))
    m.shape(dr, "rear", "box", (0.01, W - 0.04, H - 0.04), (-(D - 0.06), 0, H / 2))
    bar(m, dr, (0.01 + 0.06, 0, H / 2), vertical=False, length=0.22)
    m.joint("slide", "prismatic", "body", "drawer", axis=(1, 0, 0), limits=(0, 0.40),
            damping=4.0)
    return m


def light_door():
    W, H, D, b = 0.35, 0.50, 0.30, 0.40
    m = Model("light_door")
    carcass(m, W, H, D, b)
    door = m.link("door", (0.014, -W / 2, b), 0.6)
    m.shape(door, "panel", "box", (0.012, W - 0.006, H - 0.006), (0, W / 2, H / 2))
    bar(m, door, (0.006 + 0.055, W - 0.05, 0.30), vertical=True, length=0.16, r=0.006,
        standoff=0.055)
    m.joint("hinge", "revolute", "body", "door", axis=(0, 0, -1), limits=None, damping=2.0)
    return m


MODELS = {"wall_cabinet": (wall_cabinet, False), "wardrobe": (wardrobe, False),
          "drawer": (drawer, True), "light_door": (light_door, False)}

if __name__ == "__main__":
    for name, (make, weld) in MODELS.items():
        m = make()
        (HERE / f"{name}.sdf").write_text(m.sdf())
        if name == "wardrobe":  # a floating URDF root sits at the model frame: nest the odd
            # origin in a fixed base link instead
            mm = make()
            R0, t0 = mm.T
            mm.links.insert(0, {"name": "base", "R": np.eye(3), "t": np.zeros(3),
                                "mass": 0.1, "shapes": []})
            mm.joints.insert(0, ("base_weld", "fixed", "base", "body", np.zeros(3), None, 0))
            (HERE / f"{name}.urdf").write_text(mm.urdf())
        else:
            (HERE / f"{name}.urdf").write_text(m.urdf(weld=weld))
