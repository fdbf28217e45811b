"""`harness config show CONFIG` / `harness config schema`: a run config resolved, or every key a config takes.

``show``: the config as `harness run` reads it — its ``extends`` chain merged, every default filled
in, method entries expanded into their variants — one ``key: value  # origin`` line each, the origin
the file and line that set it or ``default`` (:mod:`harness.run.config.show`). Bad input is one line
and exit status 2, as for `harness run`.

``schema``: the reference of every section and key (type, range, default, meaning, what the value
changes), generated from the declarations (:mod:`harness.run.config.reference`): ``docs/config.md``.
"""

from __future__ import annotations

NAME = "config"
HELP = "show a run config resolved (extends merged, defaults filled in, each value's file:line), or the schema"


def add_arguments(parser) -> None:
    parser.add_argument("action", choices=("show", "schema"),
                        help="show: print the resolved config; schema: print every key a config takes (markdown)")
    parser.add_argument("config", nargs="?", help="show: the run config (YAML), e.g. ctc_configs/full.yaml")


def run(args) -> int:
    from pathlib import Path

    from harness.core.errors import InputError

    if args.action == "schema":
        from harness.run.config.reference import reference

        print(reference(), end="")
        return 0
    from harness.run.config.show import show

    if args.config is None:
        raise InputError("config show", "name the run config to show (harness config show CONFIG.yaml)")
    if not Path(args.config).exists():
        raise InputError(args.config, "cannot read config: no such file")
    print(show(args.config))
    return 0
