"""`harness` command line. Each sub-command is a module in :mod:`harness.commands` that defines

    NAME = "info"                      # the sub-command
    HELP = "one line"                  # shown in `harness --help`
    def add_arguments(parser): ...     # argparse arguments
    def run(args) -> int: ...          # exit status

Modules are discovered, so adding a command touches no shared file. Bad input anywhere raises
:class:`harness.core.errors.InputError`, printed here as one line on stderr with exit status 2.
Any other exception that reaches :func:`main` is also one line with exit status 2 — the command,
the input it read last, the exception type and message — and its traceback is printed only with
``--debug`` (anywhere on the command line) or ``HARNESS_DEBUG=1``. While a command runs, the files it
reads are recorded (:func:`harness.io.safe.recording_inputs`) so that no output replaces one.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import traceback

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
    parser.add_argument("--debug", action="store_true",
                        help="print the traceback of an unexpected error (also accepted after the command)")
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


def _debug_flag(argv: list[str]) -> tuple[list[str], bool]:
    """``argv`` without ``--debug`` (before a ``--``), and whether it was there or HARNESS_DEBUG is set."""
    end = argv.index("--") if "--" in argv else len(argv)
    debug = "--debug" in argv[:end]
    rest = [a for a in argv[:end] if a != "--debug"] + argv[end:]
    return rest, debug or os.environ.get("HARNESS_DEBUG", "") not in ("", "0")


def _unexpected_line(command: str, err: BaseException) -> str:
    """One line for an exception no command turned into an InputError: the command, the file it
    involves (its own ``filename``, else the input read last), the exception and its first line."""
    from harness.io.safe import last_input

    where = getattr(err, "filename", None) or last_input()
    text = " ".join(str(err).split())[:300] or "(no message)"
    return (f"harness: {command}: {type(err).__name__}: {text}" + (f" (last input read: {where})" if where else "")
            + "; this is a bug or an unreadable input: rerun with --debug for the traceback")


def main(argv: list[str] | None = None) -> int:
    from harness.core.lifecycle import install_signal_handlers
    from harness.io.safe import recording_inputs

    argv, debug = _debug_flag(list(sys.argv[1:] if argv is None else argv))
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    install_signal_handlers()
    with recording_inputs():  # what the command reads, no output may replace
        return _run(args, debug)


def _run(args, debug: bool) -> int:
    from harness.core.lifecycle import Terminated

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
        if debug:
            traceback.print_exc()
        from harness.io.safe import last_input

        where = last_input()
        print(f"harness: {args.command}: out of memory" + (f" (last input read: {where})" if where else "")
              + "; the input may be too large for this machine", file=sys.stderr)
        return InputError.exit_status
    except OSError as err:  # disk full, read-only, vanished folder: one line, not a traceback
        if debug:
            traceback.print_exc()
        print(f"harness: {_os_error_line(err)}", file=sys.stderr)
        return InputError.exit_status
    except Exception as err:  # the last resort: one line naming what failed (traceback with --debug)
        if debug:
            traceback.print_exc()
        print(_unexpected_line(args.command, err), file=sys.stderr)
        return InputError.exit_status


if __name__ == "__main__":
    sys.exit(main())
