"""Saving / loading learned articulation models (YAML or JSON) and SDFormat export.

File schema (YAML and JSON hold the same tree; the extension chooses the format)::

    format: mmlearn.articulation
    version: 1
    kind: link | object
    # kind == link:
    link: <LinkDict>
    # kind == object:
    object:
      parts: [name, ...]          # part names, index = part id
      root: int                   # id of the root part (object frame)
      edges:
        - {parent: int, child: int, bic: {model: float}, model: <LinkDict>}

    LinkDict:
      type: rigid | prismatic | revolute | gp | gp2..gp5
      obs: {sigma_pos: m, sigma_orient: rad, gamma_weight: w, outlier_volume_m3: m^3 | null}
      obs_fit: same, with the outlier volume used in fitting
      has_orientation: bool       # false for position-only models
      theta: [float, ...]         # parameter vector (layout: models/articulation_links.py)
      gamma: float                # outlier ratio
      n_train: int
      q_min, q_max: [float] * d   # observed configuration range (m or rad)
      log_likelihood, bic, avg_pos_error_m, avg_orient_error_rad: floats (training)
      extra: {}                   # revolute: {q_center}; gp: {dof, reduction, R_ref,
                                  #   f_mean, components, gp: GaussianProcess.to_dict()}

Floats are written with full precision (repr), so a reloaded model predicts identically.
Files are written atomically (temporary file in the same folder + os.replace).

SDFormat export (:func:`to_sdf`): one <link> per part (unit mass, small inertia, a small box
visual), the root link welded to the world, revolute / prismatic links as joints with the
learned axis and observed range as limits, rigid and GP links as fixed joints (a GP link has
no SDFormat joint type; it is frozen at the middle of its configuration range and marked in
a comment). Link poses are those at q = 0.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mmlearn.sdf.sdf_writer import Box, SdfModel

from .articulation import LinkModel, link_model_from_dict
from .articulation_structure import ArticulatedObject, LinkEdge
from .fileio import atomic_write_text

__all__ = ["model_to_dict", "model_from_dict", "save_model", "load_model", "to_sdf",
           "write_sdf", "atomic_write_text"]

FORMAT = "mmlearn.articulation"
VERSION = 1


def model_to_dict(model) -> dict:
    """Link model or ArticulatedObject -> plain dict (schema above)."""
    if isinstance(model, LinkModel):
        return {"format": FORMAT, "version": VERSION, "kind": "link", "link": model.to_dict()}
    if isinstance(model, ArticulatedObject):
        return {"format": FORMAT, "version": VERSION, "kind": "object", "object": {
            "parts": list(model.part_names), "root": int(model.root),
            "edges": [{"parent": int(e.parent), "child": int(e.child),
                       "bic": {k: float(v) for k, v in e.bic.items()},
                       "model": e.model.to_dict()} for e in model.edges]}}
    raise ValueError(f"cannot serialise {type(model).__name__}")


def model_from_dict(d: dict):
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ValueError(f"not an {FORMAT} document (format={d.get('format') if isinstance(d, dict) else None!r})")
    if int(d.get("version", 0)) != VERSION:
        raise ValueError(f"unsupported {FORMAT} version {d.get('version')}")
    if d["kind"] == "link":
        return link_model_from_dict(d["link"])
    if d["kind"] == "object":
        o = d["object"]
        edges = [LinkEdge(int(e["parent"]), int(e["child"]), link_model_from_dict(e["model"]),
                          dict(e.get("bic", {}))) for e in o["edges"]]
        return ArticulatedObject(o["parts"], int(o["root"]), edges)
    raise ValueError(f"unknown kind {d['kind']!r}")


def _is_yaml(path) -> bool:
    suf = Path(path).suffix.lower()
    if suf in (".yaml", ".yml"):
        return True
    if suf == ".json":
        return False
    raise ValueError(f"{path}: use a .json, .yaml or .yml extension")


def save_model(model, path) -> None:
    """Save a link model or ArticulatedObject as JSON or YAML (by extension), atomically."""
    d = model_to_dict(model)
    if _is_yaml(path):
        import yaml

        text = yaml.safe_dump(d, sort_keys=False, default_flow_style=None, width=100)
    else:
        text = json.dumps(d, indent=1)
    atomic_write_text(path, text)


def load_model(path):
    """Load what :func:`save_model` wrote."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: file not found")
    text = p.read_text()
    if _is_yaml(p):
        import yaml

        d = yaml.safe_load(text)
    else:
        d = json.loads(text)
    return model_from_dict(d)


# --------------------------------------------------------------------------- SDFormat
def _pose6(T: np.ndarray) -> tuple:
    """4x4 pose -> x y z roll pitch yaw (SDFormat: fixed-axis roll pitch yaw)."""
    return (*T[:3, 3], *Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))


def _pose_T(P, R=None) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = P
    if R is not None:
        T[:3, :3] = R
    return T


def _part(m: SdfModel, name: str, pose=None, relative_to=None, size: float = 0.05):
    """A part: unit mass, small inertia, a small box visual."""
    link = m.link(name, pose=pose, relative_to=relative_to)
    link.inertial(1.0, (0.001, 0.001, 0.001))
    link.visual(f"{name}_visual", Box((size, size, size)))
    return link


def _safe(name: str) -> str:
    return "".join(c if (c.isalnum() or c == "_") else "_" for c in str(name))


def to_sdf(model, *, model_name: str = "learned_object", weld_root: bool = True) -> str:
    """SDFormat 1.9 text for an ArticulatedObject (or a single link model: parts "base" and
    "part")."""
    if isinstance(model, LinkModel):
        model = ArticulatedObject(["base", "part"], 0, [LinkEdge(0, 1, model, {})])
    if not isinstance(model, ArticulatedObject):
        raise ValueError(f"cannot export {type(model).__name__} to SDFormat")
    names = [_safe(n) for n in model.part_names]
    m = SdfModel(_safe(model_name), digits=9)
    reached = {model.root}
    _part(m, names[model.root])
    if weld_root:
        m.joint(f"{names[model.root]}_weld", "fixed", "world", names[model.root])
    for e in model.edges:
        lm = e.model
        par, ch = names[e.parent], names[e.child]
        reached.add(e.child)
        jname = f"{par}__{ch}"
        if lm.name in ("revolute", "prismatic"):
            T0 = lm.forward_matrices([[0.0]])[0]  # child pose at q = 0
        elif lm.dof:
            qm = 0.5 * (lm.q_min + lm.q_max)
            T0 = lm.forward_matrices(qm[None])[0]
        else:
            T0 = lm.forward_matrices(None)[0]
        if not lm.has_orientation:
            T0[:3, :3] = np.eye(3)
        link = _part(m, ch, pose=_pose6(T0), relative_to=par)
        if lm.name == "revolute":
            from .articulation import _rv2m

            Tc = _pose_T(lm.theta[:3], _rv2m(lm.theta[3:6]))
            # joint frame = c, expressed relative to the child link frame
            m.joint(jname, "revolute", par, ch, pose=_pose6(np.linalg.inv(T0) @ Tc),
                    axis=(0, 0, 1), lower=float(lm.q_min[0]), upper=float(lm.q_max[0]))
        elif lm.name == "prismatic":
            m.joint(jname, "prismatic", par, ch, axis=T0[:3, :3].T @ lm.axis,
                    lower=float(lm.q_min[0]), upper=float(lm.q_max[0]))
        else:
            if lm.dof:
                m.comment(link.element, f"{lm.name} link (d={lm.dof}) exported frozen at "
                                        f"q={qm.tolist()}")
            m.joint(jname, "fixed", par, ch)
    for k in range(model.num_parts):
        if k not in reached:
            _part(m, names[k])
    return m.to_string()


def write_sdf(model, path, **kw) -> None:
    """Write :func:`to_sdf` atomically to ``path``."""
    atomic_write_text(path, to_sdf(model, **kw))
