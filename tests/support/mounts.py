"""Folders that behave like a full disk or a read-only volume, for tests of outputs.

Both need root to mount (a tmpfs, a read-only bind mount); ``read_only_folder`` falls back to
mode 0555 for other users (root ignores modes), ``tiny_disk`` skips the test.
"""
from __future__ import annotations

import os
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest


def _mount(*args) -> bool:
    return os.geteuid() == 0 and subprocess.run(["mount", *args], capture_output=True).returncode == 0


@contextmanager
def tiny_disk(folder: Path, size: str = "256k"):
    """``folder`` (created) as a tmpfs of ``size``: writes beyond it fail with ENOSPC."""
    folder.mkdir(parents=True, exist_ok=True)
    if not _mount("-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)):
        pytest.skip("mounting a tmpfs needs root")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


@contextmanager
def read_only_folder(folder: Path):
    """``folder`` (created, with what it holds) made read-only for the block."""
    folder.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        folder.chmod(0o555)
        try:
            yield folder
        finally:
            folder.chmod(0o755)
        return
    if not _mount("--bind", "-o", "ro", str(folder), str(folder)):
        pytest.skip("cannot make a read-only bind mount")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)
