"""Saved models (link, object, priors, demonstrations, task models): every field checked, a
checksum as the last key, so a truncated, edited or binary file is an error naming the file."""

import json
import os

import numpy as np
import pytest

from saved_files import truncation_counts, write_saved_files

from mmlearn.models.common.saved_doc import check_seal, content_checksum, read_document, seal


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    return write_saved_files(tmp_path_factory.mktemp("saved"))


def _sampled_truncations(path, loader, canonical, stride):
    """truncation_counts over every ``stride``-th offset and the last 40 (a copy)."""
    data = path.read_bytes()
    keep = set(range(0, len(data), stride)) | set(range(max(len(data) - 40, 0), len(data)))
    out = dict(errors=0, different=0, crash=0, unnamed=0, same=0)
    ref = canonical(loader(path))
    work = path.with_name("cut_" + path.name)
    work.write_bytes(data)
    try:
        for k in sorted(keep, reverse=True):
            os.truncate(work, k)
            try:
                got = canonical(loader(work))
            except (ValueError, FileNotFoundError) as e:
                out["errors" if str(work) in str(e) else "unnamed"] += 1
                continue
            except Exception:  # noqa: BLE001
                out["crash"] += 1
                continue
            out["same" if got == ref else "different"] += 1
    finally:
        work.unlink(missing_ok=True)
    return out


@pytest.mark.parametrize("name", ["link.yaml", "link.json", "object.yaml", "priors.json",
                                  "demos.json", "task.json"])
def test_truncated_files_never_load_silently_different(saved, name):
    path, loader, canonical = saved[name]
    c = _sampled_truncations(path, loader, canonical, stride=9)
    assert c["different"] == 0 and c["crash"] == 0 and c["unnamed"] == 0, c
    assert c["errors"] > 0


@pytest.mark.slow
def test_every_truncation_offset_of_every_saved_file(saved):
    for name, (path, loader, canonical) in saved.items():
        c = truncation_counts(path, loader, canonical)
        assert c["different"] == 0 and c["crash"] == 0 and c["unnamed"] == 0, (name, c)
        assert c["same"] <= 1, (name, c)  # only the cut final newline loads unchanged


@pytest.mark.parametrize("name", ["link.yaml", "object.yaml", "priors.json", "demos.json"])
def test_an_edited_value_is_a_checksum_error(saved, name, tmp_path):
    path, loader, _ = saved[name]
    text = path.read_text()
    # change one digit of the first number after the checksum-free header
    i = next(i for i, ch in enumerate(text) if ch.isdigit() and i > text.index("version") + 12)
    edited = text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1:]
    p = tmp_path / path.name
    p.write_text(edited)
    with pytest.raises(ValueError, match="checksum mismatch|must|expected") as e:
        loader(p)
    assert str(p) in str(e.value)


@pytest.mark.parametrize("name", ["link.yaml", "object.yaml", "priors.json", "demos.json",
                                  "task.json"])
def test_binary_file_is_an_error_naming_the_file(saved, name, tmp_path):
    _, loader, _ = saved[name]
    p = tmp_path / name
    p.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ValueError, match="not a text file") as e:
        loader(p)
    assert str(p) in str(e.value)


def test_reformatted_file_keeps_its_checksum(saved, tmp_path):
    import yaml

    from mmlearn.models.articulation.io import load_model, model_to_dict

    path, _, _ = saved["object.yaml"]
    doc = yaml.safe_load(path.read_text())
    p = tmp_path / "object.yaml"
    p.write_text("# re-indented by hand\n" + yaml.safe_dump(doc, default_flow_style=False))
    assert model_to_dict(load_model(p)) == model_to_dict(load_model(path))


def test_version_1_files_without_checksum_still_load(saved, tmp_path):
    from mmlearn.models.articulation.io import load_model, model_to_dict

    path, _, _ = saved["link.json"]
    doc = json.loads(path.read_text())
    doc.pop("checksum")
    doc["version"] = 1
    p = tmp_path / "old.json"
    p.write_text(json.dumps(doc))
    assert model_to_dict(load_model(p))["link"] == model_to_dict(load_model(path))["link"]
    doc["version"] = 2
    p.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="checksum missing"):
        load_model(p)


@pytest.mark.parametrize("field,value,message", [
    ("avg_orient_error_rad", "nu", "avg_orient_error_rad: expected a number or null"),
    ("n_train", 2.5, "n_train: expected an integer"),
    ("has_orientation", "yes", "has_orientation: expected true or false"),
    ("theta", [0.0, 1.0], "theta: expected 12 numbers"),
    ("extra", {}, "extra.q_center: expected a number"),
    ("q_min", [float("nan")], "non-finite"),
    ("type", "toaster", "type: expected one of"),
])
def test_every_link_field_is_checked(saved, tmp_path, field, value, message):
    from mmlearn.models.articulation.io import load_model

    doc = _yaml(saved["link.yaml"][0])  # a revolute link with orientation
    doc["link"][field] = value
    p = tmp_path / "link.json"
    p.write_text(json.dumps(seal(doc)))  # a valid checksum: the field check must catch it
    with pytest.raises(ValueError, match=message.replace("(", r"\(")) as e:
        load_model(p)
    assert str(p) in str(e.value)


def _yaml(path):
    import yaml

    return yaml.safe_load(path.read_text())


def test_seal_and_read_document(tmp_path):
    doc = seal({"format": "x", "version": 2, "a": [1.5, np.float64(2.0)]})
    assert list(doc)[-1] == "checksum" and doc["checksum"] == content_checksum(doc)
    check_seal(json.loads(json.dumps(doc, default=float)))
    with pytest.raises(ValueError, match="checksum mismatch"):
        check_seal(dict(doc, a=[1.5, 2.5]))
    with pytest.raises(ValueError, match="checksum missing"):
        check_seal({"a": 1})
    check_seal({"a": 1}, required=False)
    p = tmp_path / "list.json"
    p.write_text("[1, 2]")
    with pytest.raises(ValueError, match="expected a mapping"):
        read_document(p)
    with pytest.raises(ValueError, match="not found"):
        read_document(tmp_path / "none.json")
    with pytest.raises(ValueError, match="not a file"):
        read_document(tmp_path)
