"""Small saved files of every mmlearn saved-model format, and the truncation check used by the
tests and by docs/reliability_inputs.md: cut a file at every offset and load it."""

from __future__ import annotations

import numpy as np


def _link(kind, seed, n=25):
    from mmlearn.models.articulation.link import make_model
    from mmlearn.models.articulation.sim import simulate_link

    Z = simulate_link(kind, n, rng=seed).Z
    return make_model(kind).fit(Z, rng=seed)


def _object():
    from mmlearn.models.articulation.structure import ArticulatedObject, LinkEdge

    return ArticulatedObject(["frame", "door", "handle"], 0,
                             [LinkEdge(0, 1, _link("revolute", 1), {"revolute": -12.5}),
                              LinkEdge(1, 2, _link("rigid", 2, 12), {"rigid": -3.0})])


def _demos():
    from mmlearn.models.imitation.types import Demonstration

    t = np.linspace(0.0, 0.4, 3)
    return [Demonstration(t=t, hand=np.array([[0.1, 0.2, 0.3], [np.nan] * 3, [0.2, 0.25, 0.3]]),
                          objects={"cup": np.full((3, 3), 0.5)}, gripper=np.array([1, 0.5, 0]),
                          meta={"task": "pick_place"})]


def _task_model():
    from mmlearn.models.imitation.types import TaskModel

    return TaskModel(t=np.array([0.0, 0.2]), constraints=["obj:cup"],
                     mean={"obj:cup": np.array([[0.1, 0.0, 0.0], [0.0, 0.1, 0.0]])},
                     var={"obj:cup": np.full((2, 3), 1e-3)}, meta={"h": 0.2})


def _priors():
    from mmlearn.models.articulation.priors import PriorDatabase
    from mmlearn.models.articulation.sim import simulate_link

    db = PriorDatabase(models=("rigid", "prismatic"), max_points=8, n_hypotheses=10)
    db.add(simulate_link("prismatic", 6, rng=4).Z, "drawer", rng=4)
    return db


def write_saved_files(folder) -> dict:
    """Write one small file of each saved format into ``folder``; returns name -> (path,
    loader, canonical(loaded) -> comparable value)."""
    from pathlib import Path

    from mmlearn.models.articulation.io import load_model, model_to_dict, save_model
    from mmlearn.models.articulation.priors import PriorDatabase
    from mmlearn.models.imitation.types import (TaskModel, load_demonstrations,
                                                save_demonstrations)

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    files = {}
    save_model(_link("revolute", 0), folder / "link.yaml")
    files["link.yaml"] = (folder / "link.yaml", load_model, model_to_dict)
    save_model(_link("prismatic", 3), folder / "link.json")
    files["link.json"] = (folder / "link.json", load_model, model_to_dict)
    save_model(_object(), folder / "object.yaml")
    files["object.yaml"] = (folder / "object.yaml", load_model, model_to_dict)
    _priors().save(folder / "priors.json")
    files["priors.json"] = (folder / "priors.json", PriorDatabase.load,
                            lambda db: db.to_dict())
    save_demonstrations(folder / "demos.json", _demos())
    files["demos.json"] = (folder / "demos.json", load_demonstrations,
                           lambda ds: [_jsonable(d.to_dict()) for d in ds])
    _task_model().save(folder / "task.json")
    files["task.json"] = (folder / "task.json", TaskModel.load,
                          lambda m: _jsonable(m.to_dict()))
    return files


def _jsonable(v):
    import json

    return json.loads(json.dumps(v, default=lambda x: x.tolist()))


def truncation_counts(path, loader, canonical) -> dict:
    """Cut ``path`` at every offset 0 .. size - 1 and load each: counts of ``errors`` (a
    ValueError naming the file), ``unnamed`` (an error without the file name), ``same`` (loads
    equal to the whole file), ``different`` (loads to something else: silent nonsense) and
    ``crash`` (any other exception). Restores the file."""
    import os
    from pathlib import Path

    path = Path(path)
    data = path.read_bytes()
    ref = canonical(loader(path))
    out = dict(offsets=len(data), errors=0, unnamed=0, same=0, different=0, crash=0,
               examples=[])
    try:
        for k in range(len(data) - 1, -1, -1):  # shorten in place, longest first
            os.truncate(path, k)
            try:
                got = canonical(loader(path))
            except (ValueError, FileNotFoundError) as e:
                named = str(path) in str(e) and "\n" not in str(e)
                out["errors" if named else "unnamed"] += 1
                if not named:
                    out["examples"].append((k, str(e)))
                continue
            except Exception as e:  # noqa: BLE001 - counted, the test asserts none
                out["crash"] += 1
                out["examples"].append((k, f"{type(e).__name__}: {e}"))
                continue
            if got == ref:
                out["same"] += 1
            else:
                out["different"] += 1
                out["examples"].append((k, "loaded a different model"))
    finally:
        path.write_bytes(data)
    return out


def _without_checksum(path):
    """Rewrite ``path`` as the format's version 1 (no checksum: the field checks only)."""
    import json
    from pathlib import Path

    import yaml

    path = Path(path)
    yaml_file = path.suffix in (".yaml", ".yml")
    doc = yaml.safe_load(path.read_text()) if yaml_file else json.loads(path.read_text())
    doc.pop("checksum", None)
    doc["version"] = 1
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100)
                    if yaml_file else json.dumps(doc))


def main() -> None:  # pragma: no cover - the figures of docs/reliability_inputs.md
    """Print the truncation counts of every saved file type, with the checksum and (for
    comparison) with the field checks alone."""
    import json
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        files = write_saved_files(d)
        for name, (path, loader, canonical) in files.items():
            c = truncation_counts(path, loader, canonical)
            c.pop("examples")
            _without_checksum(path)
            v1 = truncation_counts(path, loader, canonical)
            print(json.dumps({"file": name, **c,
                              "without_checksum_different": v1["different"],
                              "without_checksum_crash": v1["crash"]}))


if __name__ == "__main__":  # pragma: no cover
    main()
