"""What the benches share: where the development data lies, and running a case in a
fresh interpreter (so that its peak memory is its own)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any, Iterable, TypeVar

T = TypeVar("T")

ROOT = Path(__file__).resolve().parents[1]
# shared/ lies beside the repository (CI clones main next to it), or beside the folder
# of git worktrees; ASSIGN5_DATA names another place.
_DATA_DIRS = [ROOT.parent / "shared" / "data", ROOT.parent.parent / "shared" / "data"]


def data_path(name: str) -> Path:
    """The development data file `name` (e.g. "intel-corrected.log.gz"); the first
    place that has it, or the first place if none does (the caller reports it)."""
    dirs = [Path(os.environ["ASSIGN5_DATA"])] if os.environ.get("ASSIGN5_DATA") else _DATA_DIRS
    return next((d / name for d in dirs if (d / name).is_file()), dirs[0] / name)


def in_own_process(module: str, *args: Any) -> dict[str, Any]:
    """Runs `python -m module --case JSON(args)` in a fresh interpreter; returns the JSON
    object it prints (its last line), or raises with the case's own error output."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    out = subprocess.run([sys.executable, "-m", module, "--case", json.dumps(list(args))],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    if out.returncode != 0:
        raise RuntimeError(f"{module} case {list(args)} failed:\n{out.stderr.strip()}")
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def progress(items: Iterable[T], desc: str, total: int | None = None) -> Iterable[T]:
    """``items`` with a tqdm bar on stderr while they run (on a terminal only), cleared after."""
    from tqdm import tqdm  # here: a case's own interpreter (its peak memory) has no bar to draw

    return tqdm(items, desc=desc, total=total, leave=False, disable=not sys.stderr.isatty(), file=sys.stderr)
