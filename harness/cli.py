"""`harness` command line. Each sub-command is a module in :mod:`harness.commands` that defines

    NAME = "info"                      # the sub-command
    HELP = "one line"                  # shown in `harness --help`
    def add_arguments(parser): ...     # argparse arguments
    def run(args) -> int: ...          # exit status

Modules are discovered, so adding a command touches no shared file. Bad input anywhere raises
:class:`harness.core.errors.InputError`, printed here as one line on stderr with exit status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys

from harness import __version__
from harness.commands import help_text
from harness.core.errors import InputError


def _command_modules():
    import harness.commands as pkg

    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            yield importlib.import_module(f"harness.commands.{info.name}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="harness",
        description="Camera-agnostic 3DGS pruning (BetaDescPrune) and its MPEG-CTC-style evaluation harness.",
    )
    parser.add_argument("--version", action="version", version=f"harness {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=help_text(mod.HELP), description=help_text(mod.HELP))
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser




def _os_error_line(err: OSError) -> str:
    """``<file>: <reason>`` of an OSError the commands did not turn into an InputError themselves
    (a disk that fills up during a run, a folder made read-only meanwhile ...)."""
    where = err.filename if err.filename is not None else "output"
    return f"{where}: {err.strerror or err}"


def main(argv: list[str] | None = None) -> int:
    from harness.core.lifecycle import Terminated, install_signal_handlers

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    install_signal_handlers()
    try:
        return int(args._run(args) or 0)
    except InputError as err:
        print(f"harness: {err}", file=sys.stderr)
        return InputError.exit_status
    except KeyboardInterrupt:
        print("harness: interrupted", file=sys.stderr)
        return 130
    except Terminated as sig:
        print(f"harness: terminated by signal {sig.signum}", file=sys.stderr)
        return 128 + sig.signum
    except BrokenPipeError:  # `harness info x | head`: the reader left, nothing to report
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except MemoryError:
        print("harness: out of memory (input too large for this machine?)", file=sys.stderr)
        return InputError.exit_status
    except OSError as err:  # disk full, read-only, vanished folder: one line, not a traceback
        print(f"harness: {_os_error_line(err)}", file=sys.stderr)
        return InputError.exit_status


if __name__ == "__main__":
    sys.exit(main())
