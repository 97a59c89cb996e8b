"""The development data (real logs and bags) for the integration tests."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest

from bench.common import data_path


@pytest.fixture(scope="session")
def dev_data() -> Callable[[str], Path]:
    """dev_data(name) -> the path of a file of the development data: ../shared/data beside
    the repository, or beside the folder of worktrees, or $ASSIGN5_DATA (bench.common's
    rule, the benches' own). A missing file fails the test that asked for it, naming the
    path: the data are part of the test set-up, never a reason to skip."""
    def path(name: str) -> Path:
        p = data_path(name)
        if not p.is_file():
            pytest.fail(f"{p} is missing: the development data (shared/data) must lie beside the repository "
                        "or in $ASSIGN5_DATA", pytrace=False)
        return p

    return path
