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
      theta: [float, ...]         # parameter vector (layout: models/articulation/links.py)
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

from mmlearn.models.common.sdf_writer import Box, SdfModel

from mmlearn.models.articulation.link import LinkModel, link_model_from_dict
from mmlearn.models.articulation.structure import ArticulatedObject, LinkEdge
from mmlearn.models.common.fileio import atomic_write_text

__all__ = ["model_to_dict", "model_from_dict", "save_model", "load_model", "to_sdf",
           "atomic_write_text", "validate_link_dict",
           "validate_prior_dict"]

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


def _non_finite(v, where: str):
    """Path of the first NaN / infinite number in a nested list/dict ``v`` (None)."""
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return None
    if isinstance(v, (int, float, np.number)):
        return None if np.isfinite(float(v)) else f"{where} = {float(v)}"
    if isinstance(v, dict):
        for k, x in v.items():
            r = _non_finite(x, f"{where}.{k}")
            if r:
                return r
    elif isinstance(v, (list, tuple, np.ndarray)):
        for i, x in enumerate(v):
            r = _non_finite(x, f"{where}[{i}]")
            if r:
                return r
    return None


LINK_KEYS = ("type", "obs", "obs_fit", "has_orientation", "theta", "gamma", "n_train", "q_min",
             "q_max", "log_likelihood", "bic", "avg_pos_error_m", "avg_orient_error_rad")


def validate_link_dict(d, where: str = "link") -> None:
    """Raise ValueError naming the problem if ``d`` is not a usable LinkDict (schema above):
    a missing key, a value of the wrong type, or a NaN / infinite parameter."""
    if not isinstance(d, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(d).__name__}")
    missing = [k for k in LINK_KEYS if k not in d]
    if missing:
        raise ValueError(f"{where}: missing key(s) {', '.join(missing)}")
    for k in ("obs", "obs_fit"):
        if not isinstance(d[k], dict):
            raise ValueError(f"{where}.{k}: expected a mapping, got {type(d[k]).__name__}")
    for k in ("theta", "q_min", "q_max"):
        if not isinstance(d[k], (list, tuple)) or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in d[k]):
            raise ValueError(f"{where}.{k}: expected a list of numbers")
    for k in ("gamma", "log_likelihood", "bic", "avg_pos_error_m"):
        if not isinstance(d[k], (int, float)) or isinstance(d[k], bool):
            raise ValueError(f"{where}.{k}: expected a number, got {d[k]!r}")
    bad = _non_finite({k: d[k] for k in ("obs", "obs_fit", "theta", "gamma", "q_min", "q_max",
                                         "extra") if k in d}, where)
    if bad:
        raise ValueError(f"{where}: non-finite value {bad}")
    if not 0.0 <= float(d["gamma"]) <= 1.0:
        raise ValueError(f"{where}.gamma: expected an outlier ratio in [0, 1], got {d['gamma']}")


def _link_from_dict(d, where: str):
    validate_link_dict(d, where)
    try:
        return link_model_from_dict(d)
    except (KeyError, TypeError, IndexError, AttributeError) as e:
        raise ValueError(f"{where}: malformed link model ({type(e).__name__}: {e})") from None


def model_from_dict(d: dict):
    """Inverse of :func:`model_to_dict`; raises ValueError naming the problem (missing key,
    wrong type, NaN) on a malformed document."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ValueError(f"not an {FORMAT} document (format={d.get('format') if isinstance(d, dict) else None!r})")
    try:
        version = int(d.get("version", 0))
    except (TypeError, ValueError):
        version = None
    if version != VERSION:
        raise ValueError(f"unsupported {FORMAT} version {d.get('version')!r}")
    kind = d.get("kind")
    if kind == "link":
        return _link_from_dict(d.get("link"), "link")
    if kind == "object":
        o = d.get("object")
        if not isinstance(o, dict):
            raise ValueError("object: missing or not a mapping")
        for k in ("parts", "root", "edges"):
            if k not in o:
                raise ValueError(f"object: missing key {k!r}")
        if not isinstance(o["parts"], list) or not isinstance(o["edges"], list):
            raise ValueError("object.parts and object.edges must be lists")
        n = len(o["parts"])
        edges = []
        for i, e in enumerate(o["edges"]):
            w = f"object.edges[{i}]"
            if not isinstance(e, dict) or not {"parent", "child", "model"} <= set(e):
                raise ValueError(f"{w}: expected a mapping with parent, child and model")
            for k in ("parent", "child"):
                if not isinstance(e[k], int) or isinstance(e[k], bool) or not 0 <= e[k] < n:
                    raise ValueError(f"{w}.{k}: expected a part index 0..{n - 1}, "
                                     f"got {e[k]!r}")
            bic = e.get("bic", {})
            if not isinstance(bic, dict):
                raise ValueError(f"{w}.bic: expected a mapping")
            edges.append(LinkEdge(e["parent"], e["child"], _link_from_dict(e["model"],
                                                                           f"{w}.model"),
                                  dict(bic)))
        if not isinstance(o["root"], int) or not 0 <= o["root"] < max(n, 1):
            raise ValueError(f"object.root: expected a part index, got {o['root']!r}")
        return ArticulatedObject(o["parts"], int(o["root"]), edges)
    raise ValueError(f"unknown kind {kind!r} (expected 'link' or 'object')")


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
    """Load what :func:`save_model` wrote. Raises ValueError naming the file and the
    problem (missing file, unparsable YAML/JSON, missing key, wrong type, NaN)."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: file not found")
    if not p.is_file():
        raise ValueError(f"{p}: not a file")
    yaml_ = _is_yaml(p)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"{p}: cannot read ({e})") from None
    if yaml_:
        import yaml

        try:
            d = yaml.safe_load(text)
        except yaml.YAMLError as e:
            raise ValueError(f"{p}: not valid YAML ({' '.join(str(e).split())})") from None
    else:
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{p}: not valid JSON ({e})") from None
    try:
        return model_from_dict(d)
    except ValueError as e:
        raise ValueError(f"{p}: {e}") from None


def validate_prior_dict(d: dict) -> None:
    """Raise ValueError naming the problem in a prior database document: a missing or
    mistyped key, NaN / infinite data, members and data of different lengths."""
    for k in ("config", "clusters"):
        if k not in d:
            raise ValueError(f"prior database: missing key {k!r}")
    c = d["config"]
    if not isinstance(c, dict):
        raise ValueError("prior database: 'config' must be a mapping")
    missing = [k for k in ("sigma_pos", "sigma_orient", "models", "align", "max_points",
                           "joint_models", "n_hypotheses") if k not in c]
    if missing:
        raise ValueError(f"prior database: config lacks {', '.join(missing)}")
    bad = _non_finite({k: c[k] for k in ("sigma_pos", "sigma_orient", "gamma_weight")
                       if k in c}, "config")
    if bad:
        raise ValueError(f"prior database: non-finite value {bad}")
    if not isinstance(d["clusters"], list):
        raise ValueError("prior database: 'clusters' must be a list")
    for i, cl in enumerate(d["clusters"]):
        w = f"clusters[{i}]"
        if not isinstance(cl, dict) or not {"members", "data", "model"} <= set(cl):
            raise ValueError(f"prior database: {w} must have members, data and model")
        if not isinstance(cl["members"], list) or not isinstance(cl["data"], list):
            raise ValueError(f"prior database: {w}.members and .data must be lists")
        if len(cl["data"]) != len(cl["members"]):
            raise ValueError(f"prior database: {w}: members and data differ in length")
        for j, x in enumerate(cl["data"]):
            try:
                a = np.asarray(x, float)
            except (TypeError, ValueError):
                raise ValueError(f"prior database: {w}.data[{j}] is not a numeric array") \
                    from None
            if a.ndim != 2 or a.shape[1] not in (3, 7) or a.shape[0] < 1:
                raise ValueError(f"prior database: {w}.data[{j}] must be (n, 3) or (n, 7), "
                                 f"got shape {a.shape}")
        bad = _non_finite(cl["data"], f"{w}.data")
        if bad:
            raise ValueError(f"prior database: non-finite value {bad}")
        try:
            validate_link_dict(cl["model"], f"{w}.model")
        except ValueError as e:
            raise ValueError(f"prior database: {e}") from None


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
            from mmlearn.models.articulation.link import _rv2m

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
