"""Outputs that appear whole or not at all: written under temporary names beside their
final paths, renamed into place only when everything was written."""
from __future__ import annotations

import os
import shutil
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


@contextmanager
def staged_folder(final: Path) -> Iterator[Path]:
    """Yields an empty temporary folder beside `final` (created first, so an output that
    cannot be written fails before any work). When the block ends without an error its
    files move into `final` (created if needed; files of the same names replaced);
    otherwise the temporary folder is removed and `final` is not touched.

    Raises:
        OSError: `final` is a file, or its folder cannot be written.
    """
    final = Path(final)
    if final.exists() and not final.is_dir():
        raise NotADirectoryError(f"--out {final} is a file, not a folder")
    work = partial_path(final)
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        work.mkdir()
    except OSError as err:
        raise OSError(err.errno, f"cannot write the output folder {final}: {err.strerror}") from None
    try:
        yield work
        try:
            final.mkdir(exist_ok=True)
            for item in sorted(work.iterdir()):
                os.replace(item, final / item.name)
            work.rmdir()
        except OSError as err:
            raise OSError(err.errno, f"cannot move the results into {final}: {err.strerror}") from None
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
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
