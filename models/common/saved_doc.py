"""Saved documents with a checksum: a truncated or edited file is an error, never a
silently different model.

Every saved model format of mmlearn (articulation link and object models, prior databases,
demonstrations, task models) is a JSON or YAML mapping that starts with ``format`` and
``version`` and, from the versions listed in the formats' docstrings on, ends with::

    checksum: sha256:<64 hex digits>

The checksum is the SHA-256 of the document's *content* (every key but ``checksum``, as
canonical JSON: sorted keys, no spaces, floats as Python's shortest round-trip text), not of
its bytes. Re-indenting the file, switching between block and flow style or adding comments
keeps it valid; any change of a value, a missing key, or a file cut short anywhere before its
last line is an error that names the file. Because ``checksum`` is the last key, a file cut
at any offset either loses it (``checksum missing: the file is truncated ...``) or cuts its
value (``checksum mismatch``); a file cut only in its final newline loads unchanged.

:func:`read_document` also turns the ways a file can fail to be text into one ``ValueError``
naming the file: missing, a folder, binary (not UTF-8), not valid JSON / YAML, not a mapping.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

__all__ = ["CHECKSUM_KEY", "content_checksum", "seal", "check_seal", "read_document"]

CHECKSUM_KEY = "checksum"


def content_checksum(doc: dict) -> str:
    """``"sha256:<hex>"`` of ``doc`` without its ``checksum`` key (canonical JSON)."""
    body = {k: v for k, v in doc.items() if k != CHECKSUM_KEY}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=True,
                      default=_plain)
    return "sha256:" + hashlib.sha256(text.encode("utf-8")).hexdigest()


def _plain(v):
    """numpy scalars and arrays as plain Python for the canonical text."""
    if hasattr(v, "tolist"):
        return v.tolist()
    raise TypeError(f"cannot checksum a {type(v).__name__}")


def seal(doc: dict) -> dict:
    """A copy of ``doc`` with its checksum as the last key."""
    body = {k: v for k, v in doc.items() if k != CHECKSUM_KEY}
    body[CHECKSUM_KEY] = content_checksum(body)
    return body


def check_seal(doc: dict, *, required: bool = True) -> None:
    """Raise ``ValueError`` when ``doc``'s checksum is missing (when ``required``), malformed
    or does not match its content."""
    if CHECKSUM_KEY not in doc:
        if required:
            raise ValueError(f"{CHECKSUM_KEY} missing: the file is truncated or was not "
                             "written by mmlearn (the checksum is its last line)")
        return
    got = doc[CHECKSUM_KEY]
    if not isinstance(got, str) or not got.startswith("sha256:"):
        raise ValueError(f"{CHECKSUM_KEY}: expected 'sha256:<hex>', got {got!r}")
    if got != content_checksum(doc):
        raise ValueError(f"{CHECKSUM_KEY} mismatch: the content differs from what was saved "
                         "(the file is truncated, damaged or was edited)")


def read_document(path, *, yaml_format: bool | None = None, what: str = "file") -> dict:
    """Parse the JSON or YAML mapping in ``path`` (YAML for a .yaml / .yml name unless
    ``yaml_format`` says otherwise). Raises ``ValueError("<path>: ...")`` for a missing file,
    a folder, a binary file, invalid JSON / YAML, or a document that is not a mapping."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: {what} not found")
    if not p.is_file():
        raise ValueError(f"{p}: not a file")
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise ValueError(f"{p}: cannot read ({e.strerror or e})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{p}: not a text file (byte {e.start} is not UTF-8; binary "
                         "or damaged?)") from None
    if "\x00" in text:
        raise ValueError(f"{p}: not a text file (contains NUL bytes; binary or damaged?)")
    if yaml_format is None:
        yaml_format = p.suffix.lower() in (".yaml", ".yml")
    if yaml_format:
        import yaml

        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when available
        try:
            doc = yaml.load(text, Loader=loader)  # noqa: S506 - a safe loader
        except yaml.YAMLError as e:
            raise ValueError(f"{p}: not valid YAML ({' '.join(str(e).split())})") from None
    else:
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{p}: not valid JSON ({e})") from None
        except RecursionError:
            raise ValueError(f"{p}: not valid JSON (nested too deeply)") from None
        except ValueError as e:  # e.g. an integer with too many digits
            raise ValueError(f"{p}: not valid JSON ({e})") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{p}: expected a mapping of keys to values, got "
                         f"{type(doc).__name__}")
    return doc
