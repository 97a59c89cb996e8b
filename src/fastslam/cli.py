"""What every command-line tool shares."""
from __future__ import annotations

import functools
import os
import sys
from typing import Any, Callable, TypeVar, cast

Main = TypeVar("Main", bound=Callable[..., int])


def closed_output_ends_quietly(main: Main) -> Main:
    """A reader that stops early (`... | head`) ends the tool with one line on stderr and
    exit status 1, not a traceback."""
    @functools.wraps(main)
    def run(*args: Any, **kwargs: Any) -> int:
        try:
            return main(*args, **kwargs)
        except BrokenPipeError:
            # later writes to stdout, Python's own flush at exit among them, go nowhere
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            print(f"{os.path.basename(sys.argv[0])}: output closed by its reader; stopped", file=sys.stderr)
            return 1
    return cast(Main, run)
