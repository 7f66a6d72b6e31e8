"""The repository speaks of the product, not of how it was developed: no issue numbers, work
sessions, branch or worktree names, people, or narratives of which seeds were seen when.

Scans every tracked text file (code, docs, tests, configuration). A hit names the file, the
line and the pattern; a legitimate use belongs in ALLOWED with a reason.
"""

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: (pattern, what it catches)
PATTERNS = [
    (r"\bissues? ?#?\d+", "an issue number"),
    (r"\bsessions?\b", "a work session"),
    (r"\bworktrees?\b", "a worktree"),
    (r"\bbranch(?:es)? (?:`|'|\"|p[a-z]+\b|main\b)", "a branch name"),
    (r"\bon (?:the )?(?:main|feature) branch\b", "a branch"),
    (r"\bcommits? [0-9a-f]{7,40}\b", "a commit hash"),
    (r"\bengineers?\b", "the people who built it"),
    (r"\bhelpers? (?:engineer|session|agent)s?\b", "the people who built it"),
    (r"\blasa\d\b", "a development name"),
    (r"\b(?:pdoor|pgap|pview|depthscene)\b", "a development name"),
    (r"looked at before|not looked at|code was final", "which seeds were seen when"),
    (r"\bfresh seeds?\b", "which seeds were seen when"),
    (r"\b(?:first|second|third|fourth|fifth|last) look at them\b", "which seeds were seen when"),
    (r"\bmeasured (?:on )?20\d\d-\d\d-\d\d\b", "a measurement date"),
    (r"\.\./shared\b|/work/shared", "a path a user does not have"),
]

#: (path regex, line regex): legitimate uses
ALLOWED = [
    (r"", r"[Mm]eshcat session"),             # a browser's connection to Meshcat
    (r"^tests/test_no_process_words\.py$", r""),  # this file names the patterns
    # benchmarks that read the full data sets from a folder given on the command line
    (r"^benchmarks/bench_(?:front_detector|grasp_variation|tactile_state)\.py$",
     r"\.\./shared|/work/shared"),
]

SKIP_SUFFIXES = {".png", ".jpg", ".npy", ".npz", ".gz", ".zip", ".pdf", ".pkl", ".obj", ".stl",
                 ".dae", ".ply", ".csv", ".jsonl", ".txt"}


def _tracked_text_files():
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.split("\n")
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    for rel in filter(None, out):
        path = ROOT / rel
        if path.suffix.lower() in SKIP_SUFFIXES or rel.startswith("tests/data/") and \
                path.suffix.lower() not in {".md", ".py"}:
            continue
        if path.is_file():
            yield rel, path


def find_process_words(rel: str, text: str) -> list[str]:
    """``file:line: pattern (what)`` for every hit in ``text`` not in ALLOWED."""
    hits = []
    for n, line in enumerate(text.splitlines(), 1):
        for pattern, what in PATTERNS:
            m = re.search(pattern, line, re.I)
            if not m:
                continue
            if any(re.search(p, rel) and re.search(l, line) for p, l in ALLOWED):
                continue
            hits.append(f"{rel}:{n}: {m.group(0)!r} ({what})")
    return hits


def test_no_development_process_words():
    hits = []
    for rel, path in _tracked_text_files():
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue
        hits += find_process_words(rel, text)
    assert not hits, "\n".join(hits[:40])


@pytest.mark.parametrize("line", [
    "Measured on fresh seeds 101-110 (not looked at before the code was final).",
    "the thesis' rate, see issue 12 item 3",
    "found in the tenth session",
    "rendered by branch `depthscene`",
    "merged from branches pdoor, pgap and pview",
    "re-measured on commit 7065857",
    "lasa5: the duration start frame",
    "the fourth look at them over all sessions",
])
def test_the_scan_catches_process_words(line):
    assert find_process_words("models/x.py", line)


@pytest.mark.parametrize("line", [
    "after a live Meshcat session in a terminal",
    "subprocess.Popen(cmd, start_new_session=True)",
    "engineered models of the intact arm (EngineeredModel)",
    "the held-back LASA shapes; progress bars and other helpers",
])
def test_the_scan_leaves_product_words(line):
    assert not find_process_words("models/x.py", line)
