"""Outputs that appear whole or not at all: written under temporary names beside their
final paths, renamed into place only when everything was written."""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

PARTIAL = ".partial-"  # temporary names: .<name>.partial-<pid>


def partial_path(final: Path) -> Path:
    """The temporary name of `final` for this process."""
    return final.with_name(f".{final.name}{PARTIAL}{os.getpid()}")


@contextmanager
def staged(*finals: Path) -> Iterator[list[Path]]:
    """Yields a temporary path for each final path. When the block ends without an
    error, each temporary is renamed onto its final path, in the order given (put the
    file whose presence tells "complete" last); otherwise every temporary is removed
    and no final path is touched."""
    temps = [partial_path(Path(f)) for f in finals]
    try:
        yield temps
        for temp, final in zip(temps, finals):
            os.replace(temp, final)
    except BaseException:
        for temp in temps:
            if temp.exists():
                temp.unlink()
        raise


def remove_stale(folder: Path, stem: str) -> list[Path]:
    """Removes temporaries of `stem` in `folder` left by killed processes (not this one's)."""
    removed = []
    for p in folder.glob(f".{stem}*{PARTIAL}*"):
        pid = p.name.rpartition(PARTIAL)[2]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            try:
                p.unlink()
            except FileNotFoundError:
                continue  # another process cleaned it first
            removed.append(p)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
