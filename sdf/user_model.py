"""A user's own furniture (an SDFormat or URDF file) as the mechanism of the opening task.

:func:`load_user_mechanism` reads the file with Drake's ``Parser`` into a plant of its own
and derives from the named joint and the collision geometry what the robot is told about
the mechanism (the thesis' robot was told a point on the handle and a pulling direction):

* the model frame M is the file's world frame; a floating root body is welded to the world
  (so is a root the file welds to its world), and the default placement puts M so that the
  model's lowest point rests on the floor and the joint's moving front faces +x (the robot
  starts about 1 m in front of the handle along the front's normal); ``pose`` overrides it;
* the moving part is every body the joint moves; the fixed part (the carcass) the bodies
  welded to the joint's parent;
* the front's normal: a prismatic joint moving (mostly) out of its front (a drawer) pulls
  along its axis; a thin moving part sliding in its own plane (a sliding door) has the
  normal of its thinnest direction; a revolute joint's front is the plane through the
  axis and the moving part's centre, its normal the axis times the radial direction. Its
  sign, and the opening direction of the joint, come from the joint's limits when only
  one direction is open, else from the given handle (in front of the front), else from the
  carcass (behind the front), else from the side on which the moving part sticks out
  further (its handle);
* a joint that may close further than its start while the carcass lies behind the front
  gets its start as the limit on the closing side in the scene (``closed_stop``): Drake
  does not collide a link with its joint's parent, so the front would otherwise swing or
  slide into the carcass when the hook touches it;
* the handle: a collision geometry of the moving part that stands more than 1 cm off the
  front face (the face of its largest geometry) within the face's outline; touching
  geometries form one handle (a bar and its posts); of several, the one farthest from a
  revolute axis or nearest the centre of a prismatic front; the handle point is the centre
  of its outermost geometry and its bar direction that geometry's longest in-plane extent.
  Without one, the handle is put on the front face 7 cm inside the edge away from the hinge
  (a door) or at the top edge's centre (a drawer), and ``handle_source`` says so.

Units are the file's (Drake reads metres); z is up (SDFormat and URDF convention). Coulomb
friction given in the file is not simulated (Drake's parser ignores it); damping is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["UserModelError", "UserMechanism", "load_user_mechanism", "add_user_model",
           "parse_pose", "parse_point", "user_model_args", "shape_points", "OPERABLE"]

OPERABLE = ("revolute", "prismatic")
_STANDOFF = 0.01     # a handle stands at least this far off the front face, m
_MARGIN = 0.03       # ... within the face's outline grown by this, m
_TOUCH = 0.005       # geometries closer than this belong to one handle, m
_EDGE_INSET = 0.07   # fallback handle: this far inside the free edge, m


class UserModelError(ValueError):
    """A user model that cannot be operated (the message is one line naming the problem)."""


def parse_pose(text: str) -> np.ndarray:
    """``"x y z roll pitch yaw"`` (m, rad) as a 4x4 transform."""
    v = _numbers(text, 6, "--model-pose", "x y z roll pitch yaw")
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", v[3:]).as_matrix()
    T[:3, 3] = v[:3]
    return T


def parse_point(text: str) -> np.ndarray:
    """``"x y z"`` (m) as a point."""
    return _numbers(text, 3, "--handle", "x y z")


def user_model_args(model_pose=None, handle=None) -> dict:
    """The ``pose`` and ``handle`` arguments of :func:`load_user_mechanism` from the flags'
    text (or arrays; None = not given)."""
    out = {}
    if model_pose is not None:
        a = np.asarray(model_pose, float) if not isinstance(model_pose, str) else None
        out["pose"] = parse_pose(model_pose) if a is None else (
            a if a.shape == (4, 4) else parse_pose(" ".join(map(str, a.ravel()))))
    if handle is not None:
        out["handle"] = parse_point(handle if isinstance(handle, str)
                                    else " ".join(map(str, np.ravel(handle))))
    return out


def _numbers(text, n, flag, what):
    try:
        v = np.array([float(t) for t in str(text).replace(",", " ").split()], float)
    except ValueError:
        raise UserModelError(f"{flag}: expected {n} numbers ({what}), got {text!r}") from None
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise UserModelError(f"{flag}: expected {n} finite numbers ({what}), got {text!r}")
    return v


# ------------------------------------------------------------------------------ geometry

def _fibonacci(n=48):
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    th = math.pi * (1 + 5 ** 0.5) * k
    return np.c_[np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)]


def shape_points(shape) -> np.ndarray | None:
    """Points on the surface of a Drake shape (its own frame) whose convex hull is the
    shape's, or close to it (curved shapes sampled); None for a half space."""
    from pydrake.geometry import (Box, Capsule, Convex, Cylinder, Ellipsoid, HalfSpace, Mesh,
                                  Sphere)

    if isinstance(shape, Box):
        s = np.array([shape.width(), shape.depth(), shape.height()]) / 2
        return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * s
    if isinstance(shape, Cylinder):
        a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
        r, h = shape.radius(), shape.length() / 2
        ring = np.c_[r * np.cos(a), r * np.sin(a)]
        return np.r_[np.c_[ring, np.full(24, -h)], np.c_[ring, np.full(24, h)]]
    if isinstance(shape, Sphere):
        return shape.radius() * _fibonacci()
    if isinstance(shape, Ellipsoid):
        return _fibonacci() * [shape.a(), shape.b(), shape.c()]
    if isinstance(shape, Capsule):
        s = shape.radius() * _fibonacci()
        h = shape.length() / 2
        return np.r_[s + [0, 0, h], s - [0, 0, h]]
    if isinstance(shape, (Mesh, Convex)):
        try:
            hull = shape.GetConvexHull()
        except Exception:  # noqa: BLE001 - a mesh format Drake cannot read: not seen
            return None
        return np.array([hull.vertex(i) for i in range(hull.num_vertices())], float)
    if isinstance(shape, HalfSpace):
        return None
    raise UserModelError(f"unsupported geometry shape {type(shape).__name__}")


@dataclass
class _Geom:
    """One geometry: its name, body, points in M (at the joint's start) and whether it is
    a collision geometry."""

    name: str
    body: str
    points: np.ndarray
    collision: bool

    @property
    def centre(self):
        return (self.points.min(axis=0) + self.points.max(axis=0)) / 2

    def volume(self) -> float:
        return float(np.prod(np.maximum(np.ptp(self.points, axis=0), 1e-3)))


def _geometries(plant, scene_graph, context, bodies, role) -> list[_Geom]:
    from pydrake.geometry import Role

    insp = scene_graph.model_inspector()
    out = []
    for b in bodies:
        X_WB = plant.EvalBodyPoseInWorld(context, b)
        for gid in plant.GetCollisionGeometriesForBody(b) if role == "collision" else \
                insp.GetGeometries(plant.GetBodyFrameIdOrThrow(b.index()), Role.kIllustration):
            pts = shape_points(insp.GetShape(gid))
            if pts is None:
                continue
            X_BG = insp.GetPoseInFrame(gid)
            X_WG = (X_WB @ X_BG).GetAsMatrix4()
            out.append(_Geom(insp.GetName(gid), b.name(), pts @ X_WG[:3, :3].T + X_WG[:3, 3],
                             role == "collision"))
    return out


# ------------------------------------------------------------------------------ the mechanism

@dataclass
class UserMechanism:
    """One joint of a user's model, placed in the world, as the opening task needs it.

    Directions are unit vectors; ``opening`` is ``sign * (q - q0)`` of the joint (rad or m,
    positive opens). Points and directions ending in ``_M`` are in the model frame M (the
    file's world frame); ``X_WM`` places M in the world.

    Attributes:
        path: the model file; joint: the joint's name; joint_type: "revolute" or
            "prismatic"; kind: the project kind it behaves like (left_door, right_door,
            dishwasher, drawer or sliding_door: the depth camera's handle conventions and
            the trial's random streams use it).
        X_WM: (4, 4) placement of the model frame in the world.
        axis_M, point_M: the joint's axis (its opening direction: a positive rotation /
            translation about it opens) and a point on it.
        sign, q0: the joint coordinate's opening sign and starting position.
        limit: the opening range from q0 (rad or m; inf when unlimited).
        normal_M, handle_M, bar_M, side_M, pull_M: the front's outward normal, the handle
            point, the bar's direction, the side the hook's rod stays on and the initial
            pulling direction.
        handle_source: "given", "geometry" (a geometry standing off the front) or
            "fallback" (the front's edge).
        handle_geometry: name of the handle's outermost geometry (None unless from
            geometry).
        normal_source: what decided the front's side ("limits", "handle", "carcass" or
            "protrusion").
        front_M: (4, 3) corners of the front face.
        bounds_M: (2, 3) the whole model's bounding box at q0.
        damping: the joint's damping from the file.
        friction: Coulomb friction simulated on the joint (0: the file's is not read).
        joints: the model's joints (name -> type name).
        closed_stop: the joint may close further than its start in the file, and the
            carcass lies behind the front: in the scene the start is the joint's limit on
            the closing side (Drake does not collide a link with its joint's parent, so
            without it the front would swing or slide into the carcass when touched).
    """

    path: str
    joint: str
    joint_type: str
    kind: str
    X_WM: np.ndarray
    axis_M: np.ndarray
    point_M: np.ndarray
    sign: float
    q0: float
    limit: float
    normal_M: np.ndarray
    handle_M: np.ndarray
    bar_M: np.ndarray
    side_M: np.ndarray
    pull_M: np.ndarray
    handle_source: str
    handle_geometry: str | None
    normal_source: str
    front_M: np.ndarray
    bounds_M: np.ndarray
    damping: float = 0.0
    friction: float = 0.0
    joints: dict = field(default_factory=dict)
    closed_stop: bool = False

    @property
    def is_revolute(self) -> bool:
        return self.joint_type == "revolute"

    @property
    def name(self) -> str:
        return f"{Path(self.path).name}:{self.joint}"

    def X_WF(self) -> np.ndarray:
        """The model frame's placement (the furniture frame of the project's mechanisms)."""
        return self.X_WM

    def _w(self, p):
        return self.X_WM[:3, :3] @ p + self.X_WM[:3, 3]

    def _r(self, d):
        return self.X_WM[:3, :3] @ d

    def axis_world(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint axis (opening direction) and a point on it, world."""
        return self._r(self.axis_M), self._w(self.point_M)

    def handle_world(self, q: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Handle point, front normal and bar direction in the world at opening ``q``."""
        from scipy.spatial.transform import Rotation

        if self.is_revolute:
            R = Rotation.from_rotvec(self.axis_M * q).as_matrix()
            p = self.point_M + R @ (self.handle_M - self.point_M)
        else:
            R = np.eye(3)
            p = self.handle_M + self.axis_M * q
        return self._w(p), self._r(R @ self.normal_M), self._r(R @ self.bar_M)

    def task_directions(self) -> tuple[np.ndarray, np.ndarray]:
        """(side, pull) in the world."""
        return self._r(self.side_M), self._r(self.pull_M)

    def front_centre(self) -> np.ndarray:
        """Centre of the closed front's face, world."""
        return self._w(self.front_M.mean(axis=0))

    def corners_world(self) -> np.ndarray:
        """The bounding box's corners of the model at the start, world (8, 3)."""
        b = self.bounds_M
        c = np.array([[x, y, z] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]])
        return c @ self.X_WM[:3, :3].T + self.X_WM[:3, 3]

    def travel(self) -> float:
        """The opening range shown (the limit, at most 120 deg or the front's depth)."""
        if self.is_revolute:
            return min(self.limit, math.radians(120))
        depth = float(np.ptp(self.bounds_M @ self.axis_M))
        return min(self.limit, max(depth, 0.3))

    def true_joint(self) -> dict:
        """The joint as the file gives it (world frame): kind, axis, a point on it, and for
        a revolute joint the radius at the handle."""
        a, p = self.axis_world()
        out = {"name": self.joint, "kind": self.joint_type, "axis": a.round(6).tolist(),
               "point": p.round(6).tolist(), "limit": None if not math.isfinite(self.limit)
               else round(self.limit, 6), "damping": self.damping,
               "handle": self.handle_world(0.0)[0].round(6).tolist(),
               "handle_source": self.handle_source, "equivalent_kind": self.kind,
               "closed_stop": self.closed_stop}
        if self.is_revolute:
            d = self.handle_world(0.0)[0] - p
            out["radius_m"] = float(np.linalg.norm(d - np.dot(d, a) * a))
        return out


# ------------------------------------------------------------------------------ loading

def _parse(path: str, plant):
    """Add the file's models to ``plant`` (auto-renamed); a one-line error when it is
    missing or does not parse."""
    from pydrake.multibody.parsing import Parser

    p = Path(path)
    if not p.is_file():
        raise UserModelError(f"--model: no such file: {path}")
    if p.suffix.lower() not in (".sdf", ".urdf", ".xml"):
        raise UserModelError(f"--model: expected an .sdf or .urdf file, got {p.name}")
    parser = Parser(plant)
    parser.SetAutoRenaming(True)
    try:
        parser.package_map().PopulateUpstreamToDrake(str(p.resolve()))
    except Exception:  # noqa: BLE001 - no package.xml above the file: nothing to add
        pass
    import logging

    log = logging.getLogger("drake")   # the parser's warnings are not the user's error
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        return parser.AddModels(str(p))
    except Exception as e:  # noqa: BLE001 - Drake's parser raises RuntimeError and others
        first = " ".join(str(e).split())
        first = first[len("error: "):] if first.lower().startswith("error: ") else first
        raise UserModelError(f"--model: cannot parse {p.name}: {first[:300]}") from None
    finally:
        log.setLevel(level)


def _find_joint(plant, instances, name):
    joints = [plant.get_joint(j) for i in instances for j in plant.GetJointIndices(i)]
    found = [j for j in joints if j.name() == name]
    if not found:
        names = ", ".join(f"{j.name()} ({j.type_name()})" for j in joints) or "none"
        raise UserModelError(f"--joint: no joint {name!r} in the model; its joints: {names}")
    j = found[0]
    if j.type_name() not in OPERABLE:
        what = {"weld": "fixed", "ball_rpy": "ball", "planar": "planar"}.get(j.type_name(),
                                                                              j.type_name())
        raise UserModelError(f"--joint: {name!r} is a {what} joint; only a revolute or "
                             f"prismatic joint can be operated")
    if j.parent_body().index() == plant.world_body().index():
        raise UserModelError(f"--joint: {name!r} connects its link to the world directly; "
                             f"give the model a fixed base link for the joint's parent")
    return j


def _weld_roots(plant, instances, X_WM) -> None:
    """Weld the models' root bodies to the world with the model frame at ``X_WM``: floating
    bodies at their default pose, roots the file welds to its world at that weld's pose."""
    from pydrake.math import RigidTransform

    T = RigidTransform(X_WM)
    world = plant.world_body()
    children = set()
    for i in instances:
        for ji in plant.GetJointIndices(i):
            j = plant.get_joint(ji)
            children.add(int(j.child_body().index()))
            if j.parent_body().index() == world.index() and j.type_name() == "weld":
                X_WC = (j.frame_on_parent().GetFixedPoseInBodyFrame() @ j.X_FM()
                        @ j.frame_on_child().GetFixedPoseInBodyFrame().inverse())
                child = j.child_body()
                plant.RemoveJoint(j)
                plant.WeldFrames(plant.world_frame(), child.body_frame(), T @ X_WC)
    for i in instances:
        for bi in plant.GetBodyIndices(i):
            b = plant.get_body(bi)
            if int(bi) not in children and bi != world.index():
                plant.WeldFrames(plant.world_frame(), b.body_frame(),
                                 T @ plant.GetDefaultFloatingBaseBodyPose(b))


def add_user_model(parser, mech: UserMechanism):
    """Add ``mech``'s model to the plant of ``parser`` (before Finalize), welded at its
    placement, without actuators; returns (model instances, the joint)."""
    plant = parser.plant()
    instances = _parse(mech.path, plant)
    for i in instances:
        for a in list(plant.GetJointActuatorIndices(i)):
            plant.RemoveJointActuator(plant.get_joint_actuator(a))
    joint = _find_joint(plant, instances, mech.joint)
    _weld_roots(plant, instances, mech.X_WM)
    joint.set_default_positions([mech.q0])
    if mech.closed_stop:
        lo, hi = joint.position_lower_limits(), joint.position_upper_limits()
        if mech.sign > 0:
            joint.set_position_limits([mech.q0], hi)
        else:
            joint.set_position_limits(lo, [mech.q0])
    return instances, joint


def _unit(v):
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else v * 0.0


def _inplane(n):
    """(e_u, e_v): horizontal and (mostly) upward axes of the plane with normal n."""
    up = np.array([0, 0, 1.0])
    e_v = up - np.dot(up, n) * n
    if np.linalg.norm(e_v) < 1e-6:
        e_v = np.array([1.0, 0, 0]) - n[0] * n
    e_v = _unit(e_v)
    return _unit(np.cross(e_v, n)), e_v


def load_user_mechanism(path, joint: str, *, pose=None, handle=None) -> UserMechanism:
    """Read ``path`` (SDFormat or URDF) and derive the mechanism of its joint ``joint`` (see
    the module docstring). ``pose``: 4x4 placement of the model frame (None = the default
    placement); ``handle``: a handle point in the model frame (None = from the geometry).
    Raises :class:`UserModelError` (one line) for a missing or unparsable file, an unknown
    joint (naming the model's joints), a joint kind that cannot be operated, or a moving
    part without collision geometry."""
    from pydrake.geometry import SceneGraph
    from pydrake.multibody.plant import MultibodyPlant

    path = str(path)
    plant = MultibodyPlant(0.0)
    sg = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(sg)
    instances = _parse(path, plant)
    j = _find_joint(plant, instances, joint)
    joints = {plant.get_joint(k).name(): plant.get_joint(k).type_name()
              for i in instances for k in plant.GetJointIndices(i)}
    _weld_roots(plant, instances, np.eye(4))
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    lo, hi = float(j.position_lower_limits()[0]), float(j.position_upper_limits()[0])
    q0 = float(np.clip(j.GetOnePosition(ctx), lo, hi))
    j.set_default_positions([q0])
    plant.SetPositions(ctx, plant.GetDefaultPositions())
    X_WP = j.frame_on_parent().CalcPoseInWorld(ctx).GetAsMatrix4()
    revolute = j.type_name() == "revolute"
    a_loc = j.revolute_axis() if revolute else j.translation_axis()
    axis = _unit(X_WP[:3, :3] @ a_loc)
    point = X_WP[:3, 3].copy()
    moving = [plant.get_body(b) for b in plant.GetBodiesKinematicallyAffectedBy([j.index()])]
    carcass = [b for b in plant.GetBodiesWeldedTo(j.parent_body())
               if b.index() != plant.world_body().index()]
    all_bodies = [plant.get_body(b) for i in instances for b in plant.GetBodyIndices(i)]
    mg = _geometries(plant, sg, ctx, moving, "collision")
    if not mg:
        raise UserModelError(f"no handle found and --handle not given: the part that joint "
                             f"{joint!r} moves has no collision geometry for the hook")
    cg = (_geometries(plant, sg, ctx, carcass, "collision")
          or _geometries(plant, sg, ctx, carcass, "illustration"))
    everything = (_geometries(plant, sg, ctx, all_bodies, "collision")
                  + _geometries(plant, sg, ctx, all_bodies, "illustration"))
    pts_all = np.concatenate([g.points for g in everything])
    bounds = np.array([pts_all.min(axis=0), pts_all.max(axis=0)])
    size = float(np.ptp(bounds, axis=0).max())
    if size > 20.0:
        raise UserModelError(f"--model: the model is {size:.0f} m across; Drake reads metres "
                             f"(scale a model made in millimetres or inches)")
    m_pts = np.concatenate([g.points for g in mg])
    vols = np.array([g.volume() for g in mg])
    centre = (np.array([g.centre for g in mg]) * vols[:, None]).sum(axis=0) / vols.sum()
    given = None if handle is None else np.asarray(handle, float)

    # the front's normal (up to its sign) and the kind of motion
    if revolute:
        r = centre - point
        r -= np.dot(r, axis) * axis
        if np.linalg.norm(r) < 0.02:
            raise UserModelError(f"--joint: the part {joint!r} moves is centred on its axis "
                                 f"(nothing to pull on a radius)")
        n0 = _unit(np.cross(axis, r))
        sliding = False
    else:
        # a thin part sliding in its own plane: its thinnest direction is across the axis
        evals, evecs = np.linalg.eigh(np.cov((m_pts - m_pts.mean(axis=0)).T))
        thin = evecs[:, 0]
        span = np.ptp(m_pts @ thin)
        sliding = (abs(np.dot(thin, axis)) < 0.3 and abs(thin[2]) < 0.5
                   and span < 0.3 * np.ptp(m_pts @ axis) and span < 0.1)
        n0 = _unit(thin - np.dot(thin, axis) * axis) if sliding else axis.copy()
    # its sign and the opening direction
    up_range, down_range = hi - q0, q0 - lo
    tiny = 1e-6
    sign, src = None, None
    if (up_range > tiny) != (down_range > tiny):
        sign, src = (1.0 if up_range > tiny else -1.0), "limits"
    if revolute or not sliding:
        if sign is not None:
            n = n0 * sign
        else:
            n, src = _front_side(n0, m_pts, cg, centre, given)
            sign = 1.0 if np.dot(n, n0) > 0 else -1.0
    else:  # sliding: the normal's side from the geometry, the opening from the limits
        n, src2 = _front_side(n0, m_pts, cg, centre, given)
        src = src or src2
        sign = sign if sign is not None else 1.0
    if abs(n[2]) > 0.6:
        raise UserModelError(f"--joint: the front that {joint!r} moves faces "
                             f"{'up' if n[2] > 0 else 'down'}; the robot opens fronts that "
                             f"face it (with z up in the model file)")
    axis_open = axis * sign
    limit = up_range if sign > 0 else down_range
    # Drake does not collide a link with its joint's parent: a front whose joint is free to
    # close further would swing into the carcass behind it; the start is its stop
    closing = down_range if sign > 0 else up_range
    behind = bool(cg) and float(np.dot(np.concatenate([g.points for g in cg]).mean(axis=0)
                                       - centre, n)) < -0.01
    closed_stop = bool(closing > tiny and behind)
    # the front face and the handle
    e_u, e_v = _inplane(n)
    panel = max(mg, key=lambda g: np.ptp(g.points @ e_u) * np.ptp(g.points @ e_v))
    F = float((panel.points @ n).max())
    u_rng = [float((panel.points @ e_u).min()), float((panel.points @ e_u).max())]
    v_rng = [float((panel.points @ e_v).min()), float((panel.points @ e_v).max())]
    pc = panel.centre
    face_c = pc + (F - np.dot(pc, n)) * n
    front = np.array([face_c + (u - np.dot(face_c, e_u)) * e_u + (v - np.dot(face_c, e_v)) * e_v
                      for u, v in ((u_rng[0], v_rng[0]), (u_rng[1], v_rng[0]),
                                   (u_rng[1], v_rng[1]), (u_rng[0], v_rng[1]))])
    hgeom = None
    if given is not None:
        h, src_h = given, "given"
        near = min(mg, key=lambda g: np.linalg.norm(g.points - given, axis=1).min())
        bar = _bar_direction(near, n, axis_open if revolute else None, e_u)
    else:
        found = _find_handle(mg, panel, n, e_u, e_v, u_rng, v_rng, F, revolute, point,
                             axis, face_c)
        if found is not None:
            g = found
            h, src_h, hgeom = g.centre, "geometry", g.name
            bar = _bar_direction(g, n, axis_open if revolute else None, e_u)
        else:
            src_h = "fallback"
            if revolute:
                rr = face_c - point - np.dot(face_c - point, axis) * axis
                rr = _unit(rr - np.dot(rr, n) * n)   # in the front's plane
                reach = float(((front - point) @ rr).max())
                h = face_c + (reach - _EDGE_INSET - np.dot(face_c - point, rr)) * rr
                bar = _unit(axis - np.dot(axis, n) * n)
            else:
                h = face_c + (v_rng[1] - np.dot(face_c, e_v) - 0.01) * e_v
                bar = e_u
    side = _unit(np.cross(n, bar))  # in the plane, across the bar
    if revolute:
        rr = h - point - np.dot(h - point, axis) * axis
        if np.dot(side, rr) < -1e-9 or (abs(np.dot(side, _unit(rr))) < 0.3 and side[2] < 0):
            side = -side
    elif sliding:
        side = -_unit(axis_open - np.dot(axis_open, n) * n)
    elif side[2] < -1e-9 or (abs(side[2]) < 0.3 and np.dot(side, e_u) < 0):
        side = -side
    pull = axis_open.copy() if sliding else n.copy()
    kind = _equivalent_kind(revolute, sliding, axis_open, n, h, point)
    X_WM = pose if pose is not None else _default_placement(n, face_c, pts_all)
    return UserMechanism(path=path, joint=joint, joint_type=j.type_name(), kind=kind,
                         X_WM=np.asarray(X_WM, float), axis_M=axis_open, point_M=point,
                         sign=sign, q0=q0, limit=float(limit), normal_M=n,
                         handle_M=np.asarray(h, float), bar_M=_unit(bar), side_M=side,
                         pull_M=_unit(pull), handle_source=src_h, handle_geometry=hgeom,
                         normal_source=src, front_M=front, bounds_M=bounds,
                         damping=float(j.default_damping_vector()[0]), joints=joints,
                         closed_stop=closed_stop)


def _front_side(n0, m_pts, carcass, centre, given):
    """The front's outward normal (n0 or -n0) and what decided it."""
    mid = float(np.dot(centre, n0))
    if given is not None and abs(np.dot(given, n0) - mid) > 0.005:
        return (n0 if np.dot(given, n0) > mid else -n0), "handle"
    if carcass:
        cc = np.concatenate([g.points for g in carcass])
        c = float(np.dot((cc.min(axis=0) + cc.max(axis=0)) / 2, n0))
        if abs(c - mid) > 0.01:
            return (n0 if c < mid else -n0), "carcass"
    s = m_pts @ n0
    out_p, out_m = s.max() - mid, mid - s.min()
    return (n0 if out_p >= out_m else -n0), "protrusion"


def _find_handle(mg, panel, n, e_u, e_v, u_rng, v_rng, F, revolute, point, axis, face_c):
    """The outermost geometry of the chosen handle (see the module docstring), or None."""
    cands = []
    for g in mg:
        if g is panel or (g.points @ n).max() <= F + _STANDOFF:
            continue
        u, v = np.dot(g.centre, e_u), np.dot(g.centre, e_v)
        if u_rng[0] - _MARGIN <= u <= u_rng[1] + _MARGIN and \
                v_rng[0] - _MARGIN <= v <= v_rng[1] + _MARGIN:
            cands.append(g)
    if not cands:
        return None
    # touching geometries are one handle
    groups: list[list] = []
    for g in cands:
        lo, hi = g.points.min(axis=0) - _TOUCH, g.points.max(axis=0) + _TOUCH
        hit = [grp for grp in groups if any(np.all(lo <= o.points.max(axis=0))
                                            and np.all(o.points.min(axis=0) <= hi)
                                            for o in grp)]
        merged = [g] + [o for grp in hit for o in grp]
        groups = [grp for grp in groups if not any(grp is h for h in hit)] + [merged]
    outer = [max(grp, key=lambda o: (o.points @ n).max()) for grp in groups]

    def score(g):
        c = g.centre
        if revolute:
            d = c - point
            return -np.linalg.norm(d - np.dot(d, axis) * axis)
        d = c - face_c
        return np.linalg.norm(d - np.dot(d, n) * n)

    return min(outer, key=score)


def _bar_direction(g, n, axis, e_u):
    """The bar's direction: the geometry's longest in-plane extent; for a round knob the
    revolute axis's in-plane direction (the hook comes from the free edge), else
    horizontal."""
    p = g.points - g.points.mean(axis=0)
    p = p - np.outer(p @ n, n)
    w, V = np.linalg.eigh(p.T @ p)
    if w[-1] > 1.5 ** 2 * max(w[-2], 1e-12):
        return _unit(V[:, -1])
    if axis is not None:
        a = axis - np.dot(axis, n) * n
        if np.linalg.norm(a) > 0.1:
            return _unit(a)
    return e_u


def _equivalent_kind(revolute, sliding, axis_open, n, h, point) -> str:
    if not revolute:
        return "sliding_door" if sliding else "drawer"
    if abs(axis_open[2]) > 0.7:
        e_y = np.cross([0, 0, 1.0], n)   # the robot's right as it faces the front
        r = h - point
        return "left_door" if np.dot(r, e_y) > 0 else "right_door"
    return "dishwasher"


def _default_placement(n, face_c, pts) -> np.ndarray:
    """The model frame's pose: the front's normal along world +x, the front's centre over
    the world origin, the lowest point on the floor."""
    yaw = -math.atan2(n[1], n[0])
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    p = pts @ R.T
    fc = R @ face_c
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [-fc[0], -fc[1], -p[:, 2].min()]
    return T

