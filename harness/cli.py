"""`harness` command line. Each sub-command is a module in :mod:`harness.commands` that defines

    NAME = "info"                      # the sub-command
    HELP = "one line"                  # shown in `harness --help`
    def add_arguments(parser): ...     # argparse arguments (the command's one parser builder)
    def run(args) -> int: ...          # exit status

Modules are discovered, so adding a command touches no shared file. ``harness NAME ...`` imports
that command's module only and is parsed by its own parser (:func:`command_parser`), so its usage,
its ``--help`` and its errors are its own, and it pays for no other command's imports; ``harness
--help`` imports none (:func:`harness.commands.catalog` reads their ``NAME`` and ``HELP``). A
builder that needs the command's arguments to decide its options (``prune``: the flags of the
chosen ``--method``; ``bench``: the chosen benchmark's) takes them as a second parameter,
``add_arguments(parser, argv)``. Unknown options, commands and choices get a "did you mean"
(:class:`Parser`). Bad input anywhere raises :class:`harness.core.errors.HarnessError` (an
``InputError``), printed here as one line on stderr with exit status 2. Any other exception that reaches :func:`main`
is also one line with exit status 2 — the command, the input it read last, the exception type and message — and its
traceback is printed only with ``--debug`` (anywhere on the command line) or ``HARNESS_DEBUG=1``. While a command
runs, the files it reads are recorded (:func:`harness.io.safe.recording_inputs`) so that no output replaces one.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import inspect
import logging
import os
import sys
import traceback

from harness import __version__
from harness.commands import catalog, help_text
from harness.core.errors import HarnessError


def _command_module(name: str):
    """The module of sub-command ``name`` (imported on its own), or None."""
    if not name.isidentifier() or name.startswith("_"):
        return None
    try:
        spec = importlib.util.find_spec(f"harness.commands.{name}")
    except (ImportError, ValueError):
        return None
    return importlib.import_module(f"harness.commands.{name}") if spec is not None else None


class Parser(argparse.ArgumentParser):
    """argparse's parser with "did you mean" for unknown options and invalid choices (commands,
    ``--renderer`` ...). ``hints`` maps option strings to a sentence for options a command knows
    of but does not take here (``prune --method lightgs --voxel``).

    An unknown option is named before anything else is said: argparse checks required arguments
    and positional choices first, so ``prune a.ply b.ply --ration 0.5`` would otherwise say only
    "one of the arguments --ratio --keep is required". A sub-parser (``bench calibrate``) reports its own unknown
    options with its own usage, instead of handing them to its parent (``harness bench``), which
    does not know the sub-command's options."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.hints: dict[str, str] = {}
        self._argv: list[str] = []

    def add_subparsers(self, **kwargs):
        kwargs.setdefault("parser_class", _SubParser)
        return super().add_subparsers(**kwargs)

    def parse_known_args(self, args=None, namespace=None):
        self._argv = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def unknown_options(self, argv) -> list[str]:
        """The words of ``argv`` (up to ``--``) that look like options and are none of this parser's:
        not an option string, ``--opt=value``, a unique abbreviation or a short option with its
        value attached (``-n16``); negative numbers are values."""
        options = [o for a in self._actions for o in a.option_strings]
        out = []
        for word in argv[: argv.index("--")] if "--" in argv else argv:
            flag = word.split("=", 1)[0]
            if not flag.startswith("-") or len(flag) < 2 or self._negative_number_matcher.match(word):
                continue
            if flag in options or (not flag.startswith("--") and flag[:2] in options):
                continue
            if flag.startswith("--") and self.allow_abbrev and [o for o in options if o.startswith(flag)]:
                continue
            out.append(word)
        return out

    def error(self, message: str):
        from harness.core.suggest import did_you_mean

        if not message.startswith("unrecognized arguments: "):
            stray = self.unknown_options(self._argv)
            if stray:  # the typo first: the missing or misread argument is often the misspelt option's
                message = "unrecognized arguments: " + " ".join(stray)
        extra = ""
        if message.startswith("unrecognized arguments: "):
            options = [o for a in self._actions for o in a.option_strings]
            for word in message.split(": ", 1)[1].split():
                flag = word.split("=", 1)[0]
                if flag.startswith("-") and len(flag) > 1:
                    extra += f"; {flag}: {self.hints[flag]}" if flag in self.hints else \
                        (f"; {flag}{did_you_mean(flag, options)}" if did_you_mean(flag, options) else "")
        elif "invalid choice: " in message and "(choose from " in message:
            value = message.split("invalid choice: ", 1)[1].split(" (choose from", 1)[0].strip("'")
            choices = [c.strip().strip("'") for c in message.split("(choose from ", 1)[1].rstrip(")").split(",")]
            extra = did_you_mean(value, choices)
        super().error(message + extra)


class _SubParser(Parser):
    """A sub-command's parser (``harness bench calibrate``): anything it does not take is its error."""

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error("unrecognized arguments: " + " ".join(extras))
        return namespace, extras


def command_parser(mod, argv=()) -> Parser:
    """The parser of one sub-command, ``harness NAME``, built from its module (and its arguments)."""
    parser = Parser(prog=f"harness {mod.NAME}", description=help_text(mod.HELP))
    wants_argv = len(inspect.signature(mod.add_arguments).parameters) > 1
    mod.add_arguments(parser, list(argv)) if wants_argv else mod.add_arguments(parser)
    parser.set_defaults(_run=mod.run, command=mod.NAME)
    return parser


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser: ``harness --help``, ``--version`` and the list of commands (names and
    one-line helps from :func:`harness.commands.catalog`: no command module is imported)."""
    parser = Parser(
        prog="harness",
        description="Camera-agnostic 3DGS pruning (BetaDescPrune) and its MPEG-CTC-style evaluation harness.",
    )
    parser.add_argument("--version", action="version", version=f"harness {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="print the traceback of an unexpected error (also accepted after the command)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for entry in catalog("harness.commands"):
        sub.add_parser(entry.name, help=help_text(entry.help), description=help_text(entry.help))
    return parser


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """``argv`` parsed by the parser of the command it names; anything else (``--help``,
    ``--version``, no or an unknown command) by the top-level parser."""
    argv = list(sys.argv[1:] if argv is None else argv)
    mod = _command_module(argv[0]) if argv and not argv[0].startswith("-") else None
    if mod is None:
        return build_parser().parse_args(argv)
    return command_parser(mod, argv[1:]).parse_args(argv[1:])


def _os_error_line(err: OSError) -> str:
    """``<file>: <reason>`` of an OSError the commands did not turn into a HarnessError themselves
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
    """One line for an exception no command turned into a HarnessError: the command, the file it
    involves (its own ``filename``, else the input read last), the exception and its first line —
    and the plugin whose code raised it, when one did (:func:`harness.core.plugins.blame`)."""
    from harness.core.plugins import ENV, blame
    from harness.io.safe import last_input

    where = getattr(err, "filename", None) or last_input()
    if isinstance(err, SystemExit):
        text = f"sys.exit({err.code!r}) was called"
    else:
        text = " ".join(str(err).split())[:300] or "(no message)"
    guest = blame(err)
    cause = (f"; raised by the plugin {guest.who}: report it to its authors, or leave it out with {ENV}"
             if guest is not None else "; this is a bug or an unreadable input")
    return (f"harness: {command}: {type(err).__name__}: {text}" + (f" (last input read: {where})" if where else "")
            + cause + ": rerun with --debug for the traceback")


class _LogLines(logging.Handler):
    """What the library logs, as lines on stderr: WARNING and above as ``harness: warning: ...``, and
    a study's own account (logger ``harness.run``, INFO: its opening line, skipped scenes, stage
    progress) as it is — the records :func:`harness.evaluate` logs instead of printing."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            line = f"harness: warning: {text}" if record.levelno >= logging.WARNING else text
            print(line, file=sys.stderr, flush=True)
        except (OSError, ValueError):  # stderr closed: nothing to tell
            pass


@contextlib.contextmanager
def _log_lines():
    """While a command runs: the library's warnings and the study's INFO records on stderr (the
    handler and the level are the command's, removed after it, so an API call made later in the
    same process prints nothing)."""
    logger, study = logging.getLogger("harness"), logging.getLogger("harness.run")
    handler, level = _LogLines(logging.INFO), study.level
    logger.addHandler(handler)
    study.setLevel(logging.INFO)
    try:
        yield
    finally:
        study.setLevel(level)
        logger.removeHandler(handler)


def main(argv: list[str] | None = None) -> int:
    from harness.core.lifecycle import install_signal_handlers
    from harness.io.safe import recording_inputs

    argv, debug = _debug_flag(list(sys.argv[1:] if argv is None else argv))
    with _log_lines():
        args = parse_args(argv)
        if not getattr(args, "_run", None):
            build_parser().print_help()
            return 2
        install_signal_handlers()
        with recording_inputs():  # what the command reads, no output may replace
            return _run(args, debug)


def _run(args, debug: bool) -> int:
    from harness.core.lifecycle import Terminated

    try:
        return int(args._run(args) or 0)
    except HarnessError as err:
        print(f"harness: {err}", file=sys.stderr)
        return HarnessError.exit_status
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
        return HarnessError.exit_status
    except OSError as err:  # disk full, read-only, vanished folder: one line, not a traceback
        if debug:
            traceback.print_exc()
        print(f"harness: {_os_error_line(err)}", file=sys.stderr)
        return HarnessError.exit_status
    except (Exception, SystemExit) as err:  # the last resort: one line naming what failed (traceback with --debug)
        from harness.core.plugins import blame

        if isinstance(err, SystemExit) and blame(err) is None:
            raise  # not a plugin's: whoever exits means it
        if debug:
            traceback.print_exc()
        print(_unexpected_line(args.command, err), file=sys.stderr)
        return HarnessError.exit_status


if __name__ == "__main__":
    sys.exit(main())
