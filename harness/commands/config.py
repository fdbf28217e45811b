"""`harness config show CONFIG`: a run config resolved, each value with its origin.

The config as `harness run` reads it — its ``extends`` chain merged, every default filled in, method
entries expanded into their variants — one ``key: value  # origin`` line each, the origin the file
and line that set it or ``default`` (:mod:`harness.run.config.show`). Bad input is one line and exit
status 2, as for `harness run`.
"""

from __future__ import annotations

NAME = "config"
HELP = "show a run config resolved (extends merged, defaults filled in), each value with its file:line"


def add_arguments(parser) -> None:
    parser.add_argument("action", choices=("show",), help="show: print the resolved config")
    parser.add_argument("config", help="run config (YAML), e.g. ctc_configs/full.yaml")


def run(args) -> int:
    from pathlib import Path

    from harness.core.errors import InputError
    from harness.run.config.show import show

    if not Path(args.config).exists():
        raise InputError(args.config, "cannot read config: no such file")
    print(show(args.config))
    return 0
