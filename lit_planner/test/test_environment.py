"""The checkout's provenance (``bench.environment``): commit and dirty state from git."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from lit_planner.bench import environment


def _git(repo: Path, *args: str) -> None:
    subprocess.run(
        ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t", *args],
        check=True, capture_output=True,
    )  # fmt: skip


def test_the_commit_label_writes_nothing_into_the_checkout(tmp_path: Path) -> None:
    """Reading the commit ran a plain `git status`, which refreshes the index: it wrote
    .git/index (and a killed or file-size-limited one left .git/index.lock, which then failed the
    user's own `git commit`)."""
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    (repo / "a.txt").write_text("a\n")
    _git(repo, "add", "a.txt")
    _git(repo, "commit", "-q", "-m", "a")
    index = repo / ".git" / "index"
    os.utime(repo / "a.txt", (1, 1))  # new stat data: a refresh would rewrite the index
    before = index.read_bytes(), index.stat().st_mtime_ns
    label = environment.commit_label(repo)
    assert label is not None and not label.endswith("-dirty")
    assert (index.read_bytes(), index.stat().st_mtime_ns) == before
    (repo / "a.txt").write_text("b\n")
    assert environment.commit_label(repo) == label + "-dirty"
