"""Saving / loading learned articulation models (YAML or JSON) and SDFormat export.

File schema (YAML and JSON hold the same tree; the extension chooses the format)::

    format: mmlearn.articulation
    version: 2                    # version 1 files (no checksum) still load
    kind: link | object
    # kind == link:
    link: <LinkDict>
    # kind == object:
    object:
      parts: [name, ...]          # part names, index = part id
      root: int                   # id of the root part (object frame)
      edges:
        - {parent: int, child: int, bic: {model: float}, model: <LinkDict>}
    checksum: sha256:<hex>        # last key, over the content (models/common/saved_doc.py)

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
Files are written atomically (temporary file in the same folder + os.replace). Loading checks
every field (present, of its type, finite, in range) and the checksum, so a truncated or
edited file is a ``ValueError`` naming the file and the field, never a different model.

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
from mmlearn.models.common.saved_doc import check_seal, read_document, seal

__all__ = ["model_to_dict", "model_from_dict", "save_model", "load_model", "to_sdf",
           "atomic_write_text", "validate_link_dict",
           "validate_prior_dict"]

FORMAT = "mmlearn.articulation"
VERSION = 2
READABLE_VERSIONS = (1, 2)  # 1: before the checksum


def model_to_dict(model) -> dict:
    """Link model or ArticulatedObject -> plain dict (schema above)."""
    if isinstance(model, LinkModel):
        return seal({"format": FORMAT, "version": VERSION, "kind": "link",
                     "link": model.to_dict()})
    if isinstance(model, ArticulatedObject):
        return seal({"format": FORMAT, "version": VERSION, "kind": "object", "object": {
            "parts": list(model.part_names), "root": int(model.root),
            "edges": [{"parent": int(e.parent), "child": int(e.child),
                       "bic": {k: float(v) for k, v in e.bic.items()},
                       "model": e.model.to_dict()} for e in model.edges]}})
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


def _is_num(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _num_list(d, k, where, n=None):
    v = d[k]
    if not isinstance(v, (list, tuple)) or not all(_is_num(x) for x in v):
        raise ValueError(f"{where}.{k}: expected a list of numbers, got {v!r}")
    if n is not None and len(v) != n:
        raise ValueError(f"{where}.{k}: expected {n} numbers, got {len(v)}")


_OBS_NUMBERS = ("sigma_pos", "sigma_orient", "gamma_weight")
# parameter vector length by type: (with orientation, position only); see links.py
_THETA_LEN = {"rigid": (6, 3), "prismatic": (9, 6), "revolute": (12, 9)}


def _check_obs(o, where):
    if not isinstance(o, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(o).__name__}")
    for k in _OBS_NUMBERS:
        if k not in o:
            raise ValueError(f"{where}: missing key {k}")
        if not _is_num(o[k]) or not np.isfinite(float(o[k])) or float(o[k]) < 0:
            raise ValueError(f"{where}.{k}: expected a finite number >= 0, got {o[k]!r}")
    v = o.get("outlier_volume_m3")
    if v is not None and (not _is_num(v) or not np.isfinite(float(v)) or float(v) <= 0):
        raise ValueError(f"{where}.outlier_volume_m3: expected a number > 0 or null, got {v!r}")
    from mmlearn.models.articulation.obs import ObservationModel

    known = {f for f in ObservationModel.__dataclass_fields__}
    unknown = sorted(set(o) - known)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(map(str, unknown))}")


def _check_extra(d, where):
    t, e = d["type"], d.get("extra")
    if not isinstance(e, dict):
        raise ValueError(f"{where}.extra: expected a mapping, got {e!r}")
    if t == "revolute":
        if "q_center" not in e or not _is_num(e["q_center"]):
            raise ValueError(f"{where}.extra.q_center: expected a number, "
                             f"got {e.get('q_center')!r}")
    elif t.startswith("gp"):
        for k in ("dof", "reduction", "R_ref", "f_mean", "components", "gp"):
            if k not in e:
                raise ValueError(f"{where}.extra: missing key {k}")
        if not isinstance(e["dof"], int) or isinstance(e["dof"], bool) or not 1 <= e["dof"] <= 5:
            raise ValueError(f"{where}.extra.dof: expected an integer 1..5, got {e['dof']!r}")
        gp = e["gp"]
        if not isinstance(gp, dict):
            raise ValueError(f"{where}.extra.gp: expected a mapping")
        for k in ("ard", "X", "Y", "log_ell", "log_sf2", "log_sn2"):
            if k not in gp:
                raise ValueError(f"{where}.extra.gp: missing key {k}")
        for k in ("X", "Y"):
            try:
                a = np.asarray(gp[k], float)
            except (TypeError, ValueError):
                raise ValueError(f"{where}.extra.gp.{k}: not a numeric array") from None
            if a.ndim != 2 or a.shape[0] < 1:
                raise ValueError(f"{where}.extra.gp.{k}: expected a non-empty 2-D array, "
                                 f"got shape {a.shape}")
        if len(gp["X"]) != len(gp["Y"]):
            raise ValueError(f"{where}.extra.gp: X and Y differ in length")


def validate_link_dict(d, where: str = "link") -> None:
    """Raise ValueError naming the field if ``d`` is not a usable LinkDict (schema above):
    a missing key, a value of the wrong type, a NaN / infinite number, a parameter vector
    of the wrong length, a configuration range with min > max."""
    if not isinstance(d, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(d).__name__}")
    missing = [k for k in LINK_KEYS + ("extra",) if k not in d]
    if missing:
        raise ValueError(f"{where}: missing key(s) {', '.join(missing)}")
    t = d["type"]
    valid_types = ("rigid", "prismatic", "revolute", "gp", "gp1", "gp2", "gp3", "gp4", "gp5")
    if t not in valid_types:
        raise ValueError(f"{where}.type: expected one of {', '.join(valid_types)}, got {t!r}")
    for k in ("obs", "obs_fit"):
        _check_obs(d[k], f"{where}.{k}")
    if not isinstance(d["has_orientation"], bool):
        raise ValueError(f"{where}.has_orientation: expected true or false, "
                         f"got {d['has_orientation']!r}")
    n_theta = _THETA_LEN.get(t)
    _num_list(d, "theta", where, None if n_theta is None
              else n_theta[0 if d["has_orientation"] else 1])
    dof = 0 if t == "rigid" else None if t.startswith("gp") else 1
    for k in ("q_min", "q_max"):
        _num_list(d, k, where, dof)
    if len(d["q_min"]) != len(d["q_max"]):
        raise ValueError(f"{where}: q_min and q_max differ in length")
    for k in ("gamma", "log_likelihood", "bic", "avg_pos_error_m"):
        if not _is_num(d[k]):
            raise ValueError(f"{where}.{k}: expected a number, got {d[k]!r}")
    if not (d["avg_orient_error_rad"] is None or _is_num(d["avg_orient_error_rad"])):
        raise ValueError(f"{where}.avg_orient_error_rad: expected a number or null, "
                         f"got {d['avg_orient_error_rad']!r}")
    if not isinstance(d["n_train"], int) or isinstance(d["n_train"], bool) or d["n_train"] < 0:
        raise ValueError(f"{where}.n_train: expected an integer >= 0, got {d['n_train']!r}")
    _check_extra(d, where)
    bad = _non_finite({k: d[k] for k in ("theta", "gamma", "q_min", "q_max", "log_likelihood",
                                         "bic", "avg_pos_error_m", "avg_orient_error_rad",
                                         "extra")}, where)
    if bad:
        raise ValueError(f"{where}: non-finite value {bad}")
    if not 0.0 <= float(d["gamma"]) <= 1.0:
        raise ValueError(f"{where}.gamma: expected an outlier ratio in [0, 1], got {d['gamma']}")
    if any(lo > hi for lo, hi in zip(d["q_min"], d["q_max"])):
        raise ValueError(f"{where}: q_min {d['q_min']} exceeds q_max {d['q_max']}")


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
    version = d.get("version")
    if isinstance(version, bool) or version not in READABLE_VERSIONS:
        raise ValueError(f"version: unsupported {FORMAT} version {version!r} (this mmlearn "
                         f"reads {', '.join(map(str, READABLE_VERSIONS))})")
    model = _model_from_checked_dict(d)
    # the fields first (a message naming the field), then the checksum (any other change)
    check_seal(d, required=version >= 2)
    return model


def _model_from_checked_dict(d: dict):
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
        if not all(isinstance(x, str) for x in o["parts"]):
            raise ValueError(f"object.parts: expected a list of names, got {o['parts']!r}")
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
            if not isinstance(bic, dict) or not all(_is_num(v) and not np.isnan(v)
                                                    for v in bic.values()):
                raise ValueError(f"{w}.bic: expected a mapping of model names to numbers")
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


def write_model_document(d: dict, path) -> None:
    """Write a model document (``model_to_dict``'s, sealed) as JSON or YAML by extension,
    atomically."""
    if _is_yaml(path):
        import yaml

        text = yaml.safe_dump(d, sort_keys=False, default_flow_style=None, width=100)
    else:
        text = json.dumps(d, indent=1)
    atomic_write_text(path, text)


def save_model(model, path) -> None:
    """Save a link model or ArticulatedObject as JSON or YAML (by extension), atomically."""
    write_model_document(model_to_dict(model), path)


def read_model_document(path):
    """``(model, document)`` of a file :func:`save_model` wrote (the document for sections
    beside the model). Raises ValueError as :func:`load_model` does."""
    p = Path(path)
    d = read_document(p, yaml_format=_is_yaml(p), what="model file")
    try:
        return model_from_dict(d), d
    except ValueError as e:
        raise ValueError(f"{p}: {e}") from None


def load_model(path):
    """Load what :func:`save_model` wrote. Raises ValueError naming the file and the
    problem (missing or binary file, unparsable YAML/JSON, missing key, wrong type, NaN,
    checksum missing or not matching: truncated or edited)."""
    return read_model_document(path)[0]


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
